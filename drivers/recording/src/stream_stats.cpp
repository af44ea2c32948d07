// SPDX-License-Identifier: Apache-2.0
/// @file stream_stats.cpp
/// @brief Counts, rates and gaps from timestamps.
#include "wallar/drivers/recording/stream_stats.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace wallar::recording {

StreamStats stream_stats(std::string name, std::span<const TimeNs> t_ns, double nominal_rate_hz) {
  StreamStats s;
  s.name = std::move(name);
  s.count = t_ns.size();
  s.nominal_rate_hz = nominal_rate_hz;
  if (t_ns.empty()) return s;
  s.first_t_ns = t_ns.front();
  s.last_t_ns = t_ns.back();
  if (t_ns.size() < 2) return s;
  std::vector<DurationNs> periods(t_ns.size() - 1);
  for (std::size_t i = 1; i < t_ns.size(); ++i) periods[i - 1] = t_ns[i] - t_ns[i - 1];
  s.mean_rate_hz = static_cast<double>(t_ns.size() - 1) / s.duration_s();
  const auto max_it = std::max_element(periods.begin(), periods.end());
  s.max_period_ns = *max_it;
  s.max_gap_at_ns = t_ns[static_cast<std::size_t>(max_it - periods.begin()) + 1];
  std::vector<DurationNs> sorted = periods;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                   sorted.end());
  s.median_period_ns = sorted[sorted.size() / 2];
  const double nominal_ns =
      nominal_rate_hz > 0.0 ? 1e9 / nominal_rate_hz : static_cast<double>(s.median_period_ns);
  for (DurationNs p : periods) {
    if (static_cast<double>(p) > 1.5 * nominal_ns) {
      ++s.gaps;
      s.missing_samples +=
          static_cast<std::uint64_t>(std::llround(static_cast<double>(p) / nominal_ns)) - 1;
    }
  }
  return s;
}

RecordingStats recording_stats(const EurocRecording& rec) {
  RecordingStats out;
  for (std::size_t c = 0; c < 2; ++c) {
    std::vector<TimeNs> t;
    t.reserve(rec.cams[c].frames.size());
    for (const FrameEntry& f : rec.cams[c].frames) t.push_back(f.t_ns);
    out.cams[c] = stream_stats("cam" + std::to_string(c), t, rec.cams[c].calib.rate_hz);
  }
  std::vector<TimeNs> t;
  t.reserve(rec.imu.size());
  for (const ImuSample& s : rec.imu) t.push_back(s.t_ns);
  out.imu = stream_stats("imu0", t, rec.imu_calib.rate_hz);
  out.ground_truth_rows = rec.ground_truth.size();
  return out;
}

}  // namespace wallar::recording
