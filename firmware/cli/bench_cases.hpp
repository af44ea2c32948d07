// SPDX-License-Identifier: Apache-2.0
/// @file bench_cases.hpp
/// @brief Benchmark cases kept in their own files, registered by `wallar bench`.
///
/// Threading: called from main() only, before the benchmarks run.
#pragma once

#include <string>

namespace wallar::cli {

/// `wallar bench track`: reads the recording set by set_track_bench_recording (throws
/// InputError when it cannot) and registers the tracker and mapper cases.
void register_track_benchmarks();
void set_track_bench_recording(const std::string& recording);

}  // namespace wallar::cli
