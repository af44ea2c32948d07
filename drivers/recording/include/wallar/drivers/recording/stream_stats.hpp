// SPDX-License-Identifier: Apache-2.0
/// @file stream_stats.hpp
/// @brief Counts, rates and gaps of a recording's streams, from timestamps alone.
///
/// Threading: pure functions.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "wallar/core/time.hpp"
#include "wallar/drivers/recording/euroc.hpp"

namespace wallar::recording {

struct StreamStats {
  std::string name;
  std::uint64_t count = 0;
  TimeNs first_t_ns = 0;
  TimeNs last_t_ns = 0;
  double nominal_rate_hz = 0.0;  //!< from sensor.yaml
  double mean_rate_hz = 0.0;     //!< (count - 1) / duration
  DurationNs median_period_ns = 0;
  DurationNs max_period_ns = 0;
  TimeNs max_gap_at_ns = 0;  //!< time of the sample that ends the largest interval
  /// Intervals longer than 1.5 nominal periods, and the samples they are missing.
  std::uint64_t gaps = 0;
  std::uint64_t missing_samples = 0;

  [[nodiscard]] double duration_s() const { return ns_to_s(last_t_ns - first_t_ns); }
};

/// Stats of one stream of increasing timestamps.
StreamStats stream_stats(std::string name, std::span<const TimeNs> t_ns, double nominal_rate_hz);

struct RecordingStats {
  StreamStats cams[2];
  StreamStats imu;
  std::uint64_t ground_truth_rows = 0;
};

RecordingStats recording_stats(const EurocRecording& rec);

}  // namespace wallar::recording
