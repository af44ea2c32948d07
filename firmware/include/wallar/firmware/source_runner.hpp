// SPDX-License-Identifier: Apache-2.0
/// @file source_runner.hpp
/// @brief Runs a sensor source on its own thread, stoppable, with errors carried back.
///
/// Threading: run_replay() is called from the supervising thread; it starts one source thread
/// (the sink is called on it), waits, and rethrows on the caller's thread whatever the source
/// threw. `stop` may be set from any thread or a signal handler.
#pragma once

#include <atomic>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/source/replay_source.hpp"

namespace wallar::firmware {

/// Plays `rec` into `sink` until it ends, `stop` is set, or `max_duration_ns` (> 0) of wall time
/// has passed.
source::ReplayStats run_replay(const recording::EurocRecording& rec,
                               const source::ReplayOptions& options, source::SensorSink& sink,
                               const std::atomic<bool>& stop, DurationNs max_duration_ns = 0);

}  // namespace wallar::firmware
