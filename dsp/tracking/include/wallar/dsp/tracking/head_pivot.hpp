// SPDX-License-Identifier: Apache-2.0
/// @file head_pivot.hpp
/// @brief Where the head turns about: the camera centre's lever from the neck's pivot, learnt
/// online from tracked poses, so a prediction through a quick turn moves the centre along the
/// arc the turn sweeps instead of on at its last velocity.
///
/// A head turns about the neck: the camera centre is c = p + R_world_cam * l, with p the pivot
/// (moving with the body at a slowly changing velocity) and l the lever in the camera frame
/// (about 10 cm behind and below the eyes on a person; "neck models" of 3-DoF headsets). With
/// constant body velocity, the change of the centre's velocity is the change of the rotation's
/// rate times l: (c_k - c_k-1)/dt_k - (c_k-1 - c_k-2)/dt_k-1 = (Rdot_k - Rdot_k-1) l, a linear
/// equation in l for each three tracked poses. Those equations are accumulated with forgetting
/// and solved with a pull toward l = 0 (no lever: the constant-velocity model), so walking, a
/// car or a still rig learn nothing and keep the old prediction.
///
/// Threading: not thread-safe; one owner (the tracking thread). Allocates nothing.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "wallar/core/time.hpp"
#include "wallar/dsp/tracking/se3.hpp"

namespace wallar::dsp {

struct HeadPivotParams {
  /// Memory of the accumulated equations: each second scales them by exp(-1 / memory_s).
  double memory_s = 5.0;
  /// The pull toward l = 0, in the equations' units (rotation-rate change squared [1/s^2]): a
  /// lever needs turns whose rate changes by more than about sqrt(this) rad/s to be learnt.
  double prior_weight = 0.04;
  /// The lever's length is clipped to this [m] (a head's pivot is within a head's size).
  double max_lever_m = 0.3;
};

class HeadPivot {
 public:
  explicit HeadPivot(const HeadPivotParams& params = {}) : params_(params) {}

  /// A tracked pose (T_cam_world) at t_ns; with `learn`, the equation it completes counts (pass
  /// false for a pose vision holds less well, a blurred frame: it still links its neighbours).
  /// Poses must come from consecutive tracked frames of one world: call break_history() after a
  /// lost frame, a new map segment, or a correction that moves the world.
  void observe(TimeNs t_ns, const SE3d& T_cam_world, bool learn = true);
  /// The next observe() starts a new run of consecutive poses (the learnt lever is kept).
  void break_history() { count_ = 0; }
  /// Forgets the lever too (a reset tracker).
  void reset();

  /// The lever l [m]: camera centre minus pivot, in the camera frame.
  const Eigen::Vector3d& lever_cam() const { return lever_cam_; }

 private:
  HeadPivotParams params_;
  struct Sample {
    TimeNs t_ns = 0;
    Eigen::Matrix3d R_world_cam = Eigen::Matrix3d::Identity();
    Eigen::Vector3d c_world = Eigen::Vector3d::Zero();
  };
  std::array<Sample, 3> history_{};  // the newest at (count_ - 1) % 3
  int count_ = 0;
  Eigen::Matrix3d H_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d lever_cam_ = Eigen::Vector3d::Zero();
};

}  // namespace wallar::dsp
