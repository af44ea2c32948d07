// SPDX-License-Identifier: Apache-2.0
/// @file static_init.cpp
/// @brief Gravity and gyro bias from a still window.
#include "wallar/dsp/imu/static_init.hpp"

#include <cmath>

namespace wallar::dsp {

std::optional<StaticImuEstimate> estimate_static_imu(std::span<const ImuSample> samples,
                                                     TimeNs t_begin_ns, TimeNs t_end_ns,
                                                     std::size_t min_samples,
                                                     const Eigen::Vector3d& accel_bias_m_s2) {
  StaticImuEstimate est;
  Eigen::Vector3d accel_sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_sum = Eigen::Vector3d::Zero();
  for (const ImuSample& s : samples) {
    if (s.t_ns < t_begin_ns || s.t_ns > t_end_ns) continue;
    if (est.samples == 0) est.t_begin_ns = s.t_ns;
    est.t_end_ns = s.t_ns;
    accel_sum += s.accel_m_s2;
    gyro_sum += s.gyro_rad_s;
    ++est.samples;
  }
  if (est.samples < min_samples || est.samples == 0) return std::nullopt;
  const double n = static_cast<double>(est.samples);
  est.mean_accel_m_s2 = accel_sum / n - accel_bias_m_s2;
  est.gyro_bias_rad_s = gyro_sum / n;

  const double mean_norm = est.mean_accel_m_s2.norm();
  double accel_var = 0.0;
  double gyro_var = 0.0;
  for (const ImuSample& s : samples) {
    if (s.t_ns < t_begin_ns || s.t_ns > t_end_ns) continue;
    const double da = (s.accel_m_s2 - accel_bias_m_s2).norm() - mean_norm;
    accel_var += da * da;
    gyro_var += (s.gyro_rad_s - est.gyro_bias_rad_s).squaredNorm();
  }
  est.accel_std_m_s2 = std::sqrt(accel_var / n);
  est.gyro_std_rad_s = std::sqrt(gyro_var / n);

  // The smallest rotation that turns the measured "up" into world +z: yaw stays free.
  est.q_world_body = Eigen::Quaterniond::FromTwoVectors(est.mean_accel_m_s2.normalized(),
                                                        Eigen::Vector3d::UnitZ());
  return est;
}

bool is_still(const StaticImuEstimate& estimate, const StillnessLimits& limits) {
  return estimate.accel_std_m_s2 <= limits.max_accel_std_m_s2 &&
         estimate.gyro_std_rad_s <= limits.max_gyro_std_rad_s;
}

}  // namespace wallar::dsp
