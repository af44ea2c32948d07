// SPDX-License-Identifier: Apache-2.0
/// @file stereo_camera.hpp
/// @brief The rectified stereo camera the tracker works in: both eyes share f, cx, cy and rows;
/// the right eye sits baseline_m along the left eye's +x. Projection and its Jacobian.
///
/// Threading: value types and pure functions.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace wallar::dsp {

/// Rectified stereo rig: both cameras share f, cx, cy; the right camera is the left one shifted
/// by +baseline_m along x.
struct StereoIntrinsics {
  double f_px = 0.0, cx_px = 0.0, cy_px = 0.0, baseline_m = 0.0;

  /// Left (u, v) and right u of a point in the left camera frame (z > 0 expected).
  [[nodiscard]] Eigen::Vector3d project(const Eigen::Vector3d& p_cam) const {
    const double iz = 1.0 / p_cam.z();
    return {f_px * p_cam.x() * iz + cx_px, f_px * p_cam.y() * iz + cy_px,
            f_px * (p_cam.x() - baseline_m) * iz + cx_px};
  }
  /// d(u, v, u_right) / d(p_cam).
  [[nodiscard]] Eigen::Matrix3d project_jacobian(const Eigen::Vector3d& p_cam) const {
    const double iz = 1.0 / p_cam.z(), fz = f_px * iz;
    Eigen::Matrix3d J;
    J << fz, 0.0, -fz * p_cam.x() * iz,  //
        0.0, fz, -fz * p_cam.y() * iz,   //
        fz, 0.0, -fz * (p_cam.x() - baseline_m) * iz;
    return J;
  }
  /// The left-camera point seen at left (u, v) with disparity d = u - u_right.
  [[nodiscard]] Eigen::Vector3d triangulate(double u_px, double v_px, double disparity_px) const {
    const double z = f_px * baseline_m / disparity_px;
    return {(u_px - cx_px) * z / f_px, (v_px - cy_px) * z / f_px, z};
  }
};

}  // namespace wallar::dsp
