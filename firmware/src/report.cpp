// SPDX-License-Identifier: Apache-2.0
/// @file report.cpp
/// @brief Stats reports.
#include "wallar/firmware/report.hpp"

#include <cstdio>

namespace wallar::firmware {

nlohmann::json to_json(const recording::StreamStats& s) {
  return {{"name", s.name},
          {"count", s.count},
          {"first_t_ns", s.first_t_ns},
          {"last_t_ns", s.last_t_ns},
          {"duration_s", s.duration_s()},
          {"nominal_rate_hz", s.nominal_rate_hz},
          {"mean_rate_hz", s.mean_rate_hz},
          {"median_period_ms", static_cast<double>(s.median_period_ns) * 1e-6},
          {"max_period_ms", static_cast<double>(s.max_period_ns) * 1e-6},
          {"max_gap_at_ns", s.max_gap_at_ns},
          {"gaps", s.gaps},
          {"missing_samples", s.missing_samples}};
}

nlohmann::json to_json(const recording::RecordingStats& s) {
  return {{"cam0", to_json(s.cams[0])},
          {"cam1", to_json(s.cams[1])},
          {"imu0", to_json(s.imu)},
          {"ground_truth_rows", s.ground_truth_rows}};
}

nlohmann::json to_json(const source::ReplayStats& s, DurationNs tolerance_ns) {
  return {{"imu_samples", s.imu_samples},
          {"frames", {s.frames[0], s.frames[1]}},
          {"pairs_delivered", s.pairs_delivered},
          {"pairs_skipped", s.pairs_skipped},
          {"pairing",
           {{"pairs", s.pairing.pairs},
            {"unpaired", {s.pairing.unpaired[0], s.pairing.unpaired[1]}},
            {"tolerance_ms", static_cast<double>(tolerance_ns) * 1e-6},
            {"mean_abs_skew_ms", s.pairing.mean_abs_skew_ns() * 1e-6},
            {"max_abs_skew_ms", static_cast<double>(s.pairing.max_abs_skew_ns) * 1e-6}}},
          {"first_t_ns", s.first_t_ns},
          {"last_t_ns", s.last_t_ns},
          {"wall_time_s", ns_to_s(s.wall_time_ns)},
          {"max_lateness_ms", static_cast<double>(s.max_lateness_ns) * 1e-6},
          {"stopped", s.stopped}};
}

namespace {
std::string line(const recording::StreamStats& s) {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "%-5s %6llu samples over %7.3f s: %8.3f Hz (nominal %g), median period %.3f ms, "
                "max %.3f ms; %llu gaps, %llu missing\n",
                s.name.c_str(), static_cast<unsigned long long>(s.count), s.duration_s(),
                s.mean_rate_hz, s.nominal_rate_hz, static_cast<double>(s.median_period_ns) * 1e-6,
                static_cast<double>(s.max_period_ns) * 1e-6,
                static_cast<unsigned long long>(s.gaps),
                static_cast<unsigned long long>(s.missing_samples));
  return buf;
}
}  // namespace

std::string to_text(const recording::RecordingStats& s) {
  std::string out = line(s.cams[0]) + line(s.cams[1]) + line(s.imu);
  out += "ground truth rows: " + std::to_string(s.ground_truth_rows) + "\n";
  return out;
}

std::string to_text(const source::ReplayStats& s, DurationNs tolerance_ns) {
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "replayed %llu IMU samples, %llu + %llu frames in %.3f s (max lateness %.3f ms)\n"
      "stereo pairing (tolerance %.3f ms): %llu pairs, unpaired left %llu, right %llu, "
      "skew mean %.3f ms max %.3f ms; delivered %llu, skipped %llu%s\n",
      static_cast<unsigned long long>(s.imu_samples), static_cast<unsigned long long>(s.frames[0]),
      static_cast<unsigned long long>(s.frames[1]), ns_to_s(s.wall_time_ns),
      static_cast<double>(s.max_lateness_ns) * 1e-6, static_cast<double>(tolerance_ns) * 1e-6,
      static_cast<unsigned long long>(s.pairing.pairs),
      static_cast<unsigned long long>(s.pairing.unpaired[0]),
      static_cast<unsigned long long>(s.pairing.unpaired[1]), s.pairing.mean_abs_skew_ns() * 1e-6,
      static_cast<double>(s.pairing.max_abs_skew_ns) * 1e-6,
      static_cast<unsigned long long>(s.pairs_delivered),
      static_cast<unsigned long long>(s.pairs_skipped), s.stopped ? " (stopped early)" : "");
  return buf;
}

}  // namespace wallar::firmware
