// SPDX-License-Identifier: Apache-2.0
/// @file se3.cpp
/// @brief SE(3) exponential (with small-angle limits) and rotation re-orthonormalisation.
#include "wallar/dsp/tracking/se3.hpp"

#include <Eigen/Geometry>
#include <cmath>

namespace wallar::dsp {

SE3d se3_exp(const Eigen::Matrix<double, 6, 1>& xi) {
  const Eigen::Vector3d v = xi.head<3>();
  const Eigen::Vector3d w = xi.tail<3>();
  const double theta = w.norm();
  const Eigen::Matrix3d Wx = skew(w);
  // Left Jacobian of SO(3): V = I + (1 - cos t)/t^2 [w]x + (t - sin t)/t^3 [w]x^2.
  double a = 0.5, b = 1.0 / 6.0;  // Taylor limits for small angles
  if (theta > 1e-5) {
    const double t2 = theta * theta;
    a = (1.0 - std::cos(theta)) / t2;
    b = (theta - std::sin(theta)) / (t2 * theta);
  }
  SE3d T = SE3d::Identity();
  T.linear() = theta > 0 ? Eigen::AngleAxisd(theta, w / theta).toRotationMatrix()
                         : Eigen::Matrix3d::Identity();
  T.translation() = (Eigen::Matrix3d::Identity() + a * Wx + b * Wx * Wx) * v;
  return T;
}

SE3d orthonormalised(const SE3d& T) {
  SE3d out = T;
  out.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
  return out;
}

}  // namespace wallar::dsp
