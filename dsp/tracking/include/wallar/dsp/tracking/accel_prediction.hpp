// SPDX-License-Identifier: Apache-2.0
/// @file accel_prediction.hpp
/// @brief The camera centre predicted through the head's accelerations, and gravity learnt from
/// tracked poses: the accelerometer's specific force, integrated over each frame interval in the
/// IMU frame at its start (preintegration, GyroDelta::dv_m_s and dp_m), joined to the poses
/// vision solved.
///
/// Over an interval of dt seconds starting at IMU pose (R0, p0) with velocity v0, the IMU moves
/// to p1 = p0 + v0 dt + g dt^2 / 2 + R0 dp, and its velocity becomes v1 = v0 + g dt + R0 dv.
/// With two solved poses per interval the velocities, and from three poses gravity, follow.
///
/// Threading: pure functions; nothing allocates.
#pragma once

#include <Eigen/Core>

#include "wallar/dsp/tracking/se3.hpp"

namespace wallar::dsp {

/// One frame interval's integrated specific force (bias subtracted), in the IMU frame at the
/// interval's start, and its length.
struct SpecificForceInterval {
  Eigen::Vector3d dv_m_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d dp_m = Eigen::Vector3d::Zero();
  double dt_s = 0.0;
};

/// The IMU's velocity at the end of `interval`, from its poses at both ends (world <- IMU) and
/// gravity in the same world.
[[nodiscard]] Eigen::Vector3d imu_velocity_at_end(const SE3d& T_world_imu0,
                                                  const SE3d& T_world_imu1,
                                                  const SpecificForceInterval& interval,
                                                  const Eigen::Vector3d& g_world_m_s2);

/// Where the IMU will be at the end of `next`, which starts at T_world_imu1 where `last` ended
/// (last started at T_world_imu0).
[[nodiscard]] Eigen::Vector3d predict_imu_position(const SE3d& T_world_imu0,
                                                   const SE3d& T_world_imu1,
                                                   const SpecificForceInterval& last,
                                                   const SpecificForceInterval& next,
                                                   const Eigen::Vector3d& g_world_m_s2);

/// Gravity in the world from three consecutive IMU poses and the two intervals between them:
/// the velocity at the middle pose computed from either side differs by gravity times the
/// intervals' mean length. Pixel noise over dt^2 makes one estimate noisy: average them.
[[nodiscard]] Eigen::Vector3d gravity_from_poses(const SE3d& T_world_imu0, const SE3d& T_world_imu1,
                                                 const SE3d& T_world_imu2,
                                                 const SpecificForceInterval& first,
                                                 const SpecificForceInterval& second);

}  // namespace wallar::dsp
