// SPDX-License-Identifier: Apache-2.0
/// @file se3.hpp
/// @brief The few Lie-group pieces the tracker and bundle adjustment share: the skew matrix, the
/// SE(3) exponential of a twist, and re-projection of a composed pose onto SO(3).
///
/// Threading: pure functions.
#pragma once

#include <Eigen/Core>

#include "wallar/core/pose.hpp"

namespace wallar::dsp {

/// [v]x: skew(v) * w = v.cross(w).
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

/// exp of a twist xi = (v, w) (translation part first, then rotation vector) as a rigid
/// transform. Poses are perturbed on the left: T <- se3_exp(xi) * T.
SE3d se3_exp(const Eigen::Matrix<double, 6, 1>& xi);

/// T with its rotation projected back onto SO(3). Composed poses drift off it by rounding, and
/// Isometry3d's inverse (a transpose) amplifies that drift frame after frame.
SE3d orthonormalised(const SE3d& T);

}  // namespace wallar::dsp
