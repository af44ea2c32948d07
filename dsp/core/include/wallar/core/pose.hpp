// SPDX-License-Identifier: Apache-2.0
/// @file pose.hpp
/// @brief Rigid transforms named by their frames: T_a_b maps b coordinates into a.
///
/// Threading: value types.
#pragma once

#include <Eigen/Geometry>

#include "wallar/core/time.hpp"

namespace wallar {

/// A rigid-body transform. `SE3d T_world_cam; p_world = T_world_cam * p_cam;`
using SE3d = Eigen::Isometry3d;

/// A pose at a time: T_world_body valid at t_ns.
struct StampedPose {
  TimeNs t_ns = 0;
  SE3d T_world_body = SE3d::Identity();
};

/// Builds T from a unit quaternion (w, x, y, z) and a translation.
inline SE3d make_se3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
  SE3d T = SE3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = t;
  return T;
}

}  // namespace wallar
