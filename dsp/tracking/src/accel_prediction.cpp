// SPDX-License-Identifier: Apache-2.0
/// @file accel_prediction.cpp
/// @brief Preintegrated specific force joined to solved poses: velocity, position, gravity.
#include "wallar/dsp/tracking/accel_prediction.hpp"

#include <algorithm>

namespace wallar::dsp {
namespace {

/// The velocity at the start of `interval` less g dt / 2 (what the two poses and the specific
/// force give without gravity).
Eigen::Vector3d start_velocity_without_gravity(const SE3d& T_world_imu0, const SE3d& T_world_imu1,
                                               const SpecificForceInterval& interval) {
  return (T_world_imu1.translation() - T_world_imu0.translation() -
          T_world_imu0.linear() * interval.dp_m) /
         interval.dt_s;
}

}  // namespace

Eigen::Vector3d imu_velocity_at_end(const SE3d& T_world_imu0, const SE3d& T_world_imu1,
                                    const SpecificForceInterval& interval,
                                    const Eigen::Vector3d& g_world_m_s2) {
  // v0 = (p1 - p0 - R0 dp) / dt - g dt / 2, and v1 = v0 + g dt + R0 dv.
  return start_velocity_without_gravity(T_world_imu0, T_world_imu1, interval) +
         0.5 * interval.dt_s * g_world_m_s2 + T_world_imu0.linear() * interval.dv_m_s;
}

Eigen::Vector3d predict_imu_position(const SE3d& T_world_imu0, const SE3d& T_world_imu1,
                                     const SpecificForceInterval& last,
                                     const SpecificForceInterval& next,
                                     const Eigen::Vector3d& g_world_m_s2) {
  const Eigen::Vector3d v1 = imu_velocity_at_end(T_world_imu0, T_world_imu1, last, g_world_m_s2);
  return T_world_imu1.translation() + v1 * next.dt_s + 0.5 * next.dt_s * next.dt_s * g_world_m_s2 +
         T_world_imu1.linear() * next.dp_m;
}

Eigen::Vector3d gravity_from_poses(const SE3d& T_world_imu0, const SE3d& T_world_imu1,
                                   const SE3d& T_world_imu2, const SpecificForceInterval& first,
                                   const SpecificForceInterval& second) {
  // v1 from the second interval: (p2 - p1 - R1 dp2) / dt2 - g dt2 / 2; from the first:
  // (p1 - p0 - R0 dp1) / dt1 + g dt1 / 2 + R0 dv1. Equal, so g (dt1 + dt2) / 2 is their
  // difference.
  const Eigen::Vector3d after = start_velocity_without_gravity(T_world_imu1, T_world_imu2, second);
  const Eigen::Vector3d before = start_velocity_without_gravity(T_world_imu0, T_world_imu1, first) +
                                 T_world_imu0.linear() * first.dv_m_s;
  return 2.0 * (after - before) / (first.dt_s + second.dt_s);
}

bool GravityEstimate::add(const Eigen::Vector3d& g_world_m_s2) {
  if (!g_world_m_s2.allFinite()) return false;
  if (samples_ >= params_.gate_after && (g_world_m_s2 - g_).norm() > params_.gate_m_s2) {
    return false;
  }
  if (samples_ == 0) g_.setZero();
  const double alpha = 1.0 / std::min<double>(samples_ + 1, std::max(1, params_.average_frames));
  g_ += alpha * (g_world_m_s2 - g_);
  ++samples_;
  return true;
}

}  // namespace wallar::dsp
