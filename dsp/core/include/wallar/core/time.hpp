// SPDX-License-Identifier: Apache-2.0
/// @file time.hpp
/// @brief Time is int64 nanoseconds of CLOCK_MONOTONIC everywhere (t_ns).
///
/// Threading: free functions, all thread-safe.
#pragma once

#include <cstdint>
#include <ctime>

namespace wallar {

/// A point in time: nanoseconds of CLOCK_MONOTONIC (or of the recording's clock on replay).
using TimeNs = std::int64_t;
/// A span of time in nanoseconds.
using DurationNs = std::int64_t;

inline constexpr DurationNs kNsPerUs = 1'000;
inline constexpr DurationNs kNsPerMs = 1'000'000;
inline constexpr DurationNs kNsPerS = 1'000'000'000;

/// Now, in nanoseconds of CLOCK_MONOTONIC.
inline TimeNs monotonic_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<TimeNs>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

inline constexpr double ns_to_s(DurationNs t_ns) { return static_cast<double>(t_ns) * 1e-9; }
inline constexpr DurationNs s_to_ns(double t_s) { return static_cast<DurationNs>(t_s * 1e9); }

inline timespec ns_to_timespec(TimeNs t_ns) {
  return timespec{static_cast<time_t>(t_ns / kNsPerS), static_cast<long>(t_ns % kNsPerS)};
}

}  // namespace wallar
