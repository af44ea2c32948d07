// SPDX-License-Identifier: Apache-2.0
/// @file attitude_errors.cpp
/// @brief Tilt and gyro-bias errors against ground truth.
#include "wallar/dsp/imu/attitude_errors.hpp"

#include <algorithm>
#include <cmath>

#include "wallar/dsp/imu/attitude_filter.hpp"

namespace wallar::dsp {

AttitudeErrorSample attitude_error(TimeNs t_ns, const Eigen::Quaterniond& q_world_imu_est,
                                   const Eigen::Vector3d& gyro_bias_est_rad_s,
                                   const Eigen::Quaterniond& q_world_imu_true,
                                   const Eigen::Vector3d& gyro_bias_true_rad_s) {
  return AttitudeErrorSample{t_ns, tilt_error_rad(q_world_imu_est, q_world_imu_true),
                             gyro_bias_est_rad_s - gyro_bias_true_rad_s};
}

AttitudeErrorSummary summarize_attitude_errors(std::span<const AttitudeErrorSample> errors,
                                               double bias_window_s) {
  AttitudeErrorSummary s;
  if (errors.empty()) return s;
  constexpr double kDeg = 180.0 / M_PI;
  s.samples = errors.size();
  s.duration_s = ns_to_s(errors.back().t_ns - errors.front().t_ns);
  const TimeNs window_start_ns =
      std::max(errors.front().t_ns, errors.back().t_ns - s_to_ns(bias_window_s));
  s.bias_window_s = ns_to_s(errors.back().t_ns - window_start_ns);
  double tilt_sq = 0.0;
  double bias_sq = 0.0;
  std::size_t bias_n = 0;
  for (const AttitudeErrorSample& e : errors) {
    tilt_sq += e.tilt_rad * e.tilt_rad;
    s.tilt_max_deg = std::max(s.tilt_max_deg, e.tilt_rad * kDeg);
    const double b = e.gyro_bias_error_rad_s.norm();
    s.bias_error_max_rad_s = std::max(s.bias_error_max_rad_s, b);
    if (e.t_ns >= window_start_ns) {
      bias_sq += b * b;
      ++bias_n;
    }
  }
  s.tilt_rms_deg = std::sqrt(tilt_sq / static_cast<double>(s.samples)) * kDeg;
  s.tilt_final_deg = errors.back().tilt_rad * kDeg;
  s.bias_error_final_rad_s = errors.back().gyro_bias_error_rad_s.norm();
  s.bias_error_rms_rad_s =
      std::sqrt(bias_sq / static_cast<double>(std::max<std::size_t>(bias_n, 1)));
  return s;
}

}  // namespace wallar::dsp
