// SPDX-License-Identifier: Apache-2.0
/// @file gyro_integration.cpp
/// @brief Midpoint integration of bias-corrected gyro rates over a camera interval.
#include "wallar/dsp/imu/gyro_integration.hpp"

#include <algorithm>
#include <cmath>

namespace wallar::dsp {
namespace {

Eigen::Quaterniond exp_rotation(const Eigen::Vector3d& phi) {
  const double angle = phi.norm();
  if (angle < 1e-12) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, phi / angle));
}

/// One constant-rate, constant-force step of h seconds: the specific force is rotated into the
/// start frame at the step's midpoint attitude.
void step(GyroDelta& d, const Eigen::Vector3d& w_rad_s, const Eigen::Vector3d& f_m_s2, double h) {
  const Eigen::Vector3d f_start = (d.q_start_end * exp_rotation(0.5 * h * w_rad_s)) * f_m_s2;
  d.dp_m += d.dv_m_s * h + 0.5 * h * h * f_start;
  d.dv_m_s += h * f_start;
  d.q_start_end = d.q_start_end * exp_rotation(w_rad_s * h);
}

}  // namespace

GyroDelta integrate_gyro(std::span<const ImuSample> older, std::span<const ImuSample> newer,
                         TimeNs t0_cam_ns, TimeNs t1_cam_ns, const Eigen::Vector3d& bias_rad_s,
                         const GyroIntegrationOptions& options) {
  GyroDelta out;
  if (t1_cam_ns <= t0_cam_ns) return out;
  // The interval on the IMU's clock.
  const TimeNs t0 = t0_cam_ns + options.timeshift_cam_imu_ns;
  const TimeNs t1 = t1_cam_ns + options.timeshift_cam_imu_ns;
  const std::size_t n = older.size() + newer.size();
  const auto at = [&](std::size_t i) -> const ImuSample& {
    return i < older.size() ? older[i] : newer[i - older.size()];
  };
  DurationNs covered = 0;
  const ImuSample* last = nullptr;
  for (std::size_t k = 1; k < n; ++k) {
    const ImuSample& a = at(k - 1);
    const ImuSample& b = at(k);
    const TimeNs s0 = std::max(a.t_ns, t0), s1 = std::min(b.t_ns, t1);
    if (b.t_ns > t0) last = &b;
    if (s1 <= s0) continue;
    const Eigen::Vector3d w = 0.5 * (a.gyro_rad_s + b.gyro_rad_s) - bias_rad_s;
    const Eigen::Vector3d f = 0.5 * (a.accel_m_s2 + b.accel_m_s2) - options.accel_bias_m_s2;
    step(out, w, f, ns_to_s(s1 - s0));
    covered += s1 - s0;
    ++out.samples;
  }
  // The newest sample before the interval's end: hold its rate over what is left (the IMU
  // sample after the frame may not have arrived yet).
  if (last != nullptr && last->t_ns < t1) {
    const TimeNs s0 = std::max(last->t_ns, t0);
    const DurationNs gap = std::min<DurationNs>(t1 - s0, options.max_extrapolation_ns);
    if (gap > 0) {
      step(out, last->gyro_rad_s - bias_rad_s, last->accel_m_s2 - options.accel_bias_m_s2,
           ns_to_s(gap));
      covered += gap;
    }
  }
  out.q_start_end.normalize();
  out.covered_s = ns_to_s(covered);
  out.valid = static_cast<double>(covered) >= options.min_coverage * static_cast<double>(t1 - t0);
  return out;
}

}  // namespace wallar::dsp
