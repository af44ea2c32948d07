// SPDX-License-Identifier: Apache-2.0
/// @file imu_cam_rotation.hpp
/// @brief The IMU-to-camera rotation R_cam_imu from matched relative rotations: the gyro's,
/// integrated between two camera frames, and the camera's own (e.g. from the essential matrix
/// of the two images), solved by Kabsch/SVD on the rotation vectors.
///
/// Over the same interval the camera turns by R_cam_imu * Exp(rotvec_imu) * R_cam_imu^T, so its
/// rotation vector is R_cam_imu * rotvec_imu. Pairs of small rotations about at least two
/// different axes fix R_cam_imu; rotations about one axis only leave a rotation about that
/// axis free (reported by `min_axis_spread`).
///
/// Threading: pure functions; no state.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <span>

#include "wallar/core/imu_sample.hpp"

namespace wallar::dsp {

/// The rotation the gyro measures from t_begin_ns to t_end_ns, as a rotation vector in the IMU
/// frame at t_begin (R_imu0_imu1 = Exp(result)). Samples are integrated piecewise (the rate
/// interpolated linearly between samples, clipped to the window: a window shifted by a
/// fraction of a sample period changes the result continuously, which a time-offset search
/// needs) with `gyro_bias_rad_s` removed. Nothing when the samples do not cover the window.
std::optional<Eigen::Vector3d> integrate_gyro_rotvec(std::span<const ImuSample> samples,
                                                     TimeNs t_begin_ns, TimeNs t_end_ns,
                                                     const Eigen::Vector3d& gyro_bias_rad_s);

struct ImuCamRotationResult {
  Eigen::Matrix3d R_cam_imu = Eigen::Matrix3d::Identity();
  std::size_t pairs = 0;
  double residual_rms_rad = 0.0;  //!< RMS of |rotvec_cam - R_cam_imu rotvec_imu|
  /// Square root of the second-largest eigenvalue of the IMU rotation vectors' scatter,
  /// divided by the largest: 0 when all rotations share one axis (R not determined).
  double min_axis_spread = 0.0;
};

/// Solves R_cam_imu minimising sum |rotvec_cam[i] - R rotvec_imu[i]|^2 (a proper rotation,
/// det +1). Nothing when fewer than 2 pairs or the sizes differ.
std::optional<ImuCamRotationResult> solve_R_cam_imu(std::span<const Eigen::Vector3d> rotvec_imu,
                                                    std::span<const Eigen::Vector3d> rotvec_cam);

}  // namespace wallar::dsp
