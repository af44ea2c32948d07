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
/// Threading: pure functions and a value class (GravityEstimate, one owner); nothing allocates.
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

/// How GravityEstimate averages and gates.
struct GravityParams {
  int average_frames = 100;
  double gate_m_s2 = 4.0;
  int gate_after = 20;
};

/// Gravity in a map's world, averaged over per-frame estimates: the running mean of the first
/// `average_frames`, then an exponential average over that many. Once `gate_after` estimates are
/// in, one further than `gate_m_s2` from the average is dropped (a pose that jumped: a
/// relocalisation, a correction); not before, so a first estimate taken while the head
/// accelerated cannot shut out the right ones.
class GravityEstimate {
 public:
  explicit GravityEstimate(const GravityParams& params = {}) : params_(params) {}
  /// Adds one estimate; false when it was dropped (not finite, or gated).
  bool add(const Eigen::Vector3d& g_world_m_s2);
  void reset() { samples_ = 0; }
  /// Turns the estimate with the world (a correction moved the map by R_new_old).
  void rotate(const Eigen::Matrix3d& R_new_old) { g_ = R_new_old * g_; }
  [[nodiscard]] int samples() const { return samples_; }
  [[nodiscard]] const Eigen::Vector3d& value() const { return g_; }

 private:
  GravityParams params_;
  Eigen::Vector3d g_ = Eigen::Vector3d::Zero();
  int samples_ = 0;
};

}  // namespace wallar::dsp
