// SPDX-License-Identifier: Apache-2.0
/// @file imu_cam_calibration.hpp
/// @brief R_cam_imu of a recording's left camera, from the gyro against the images: what
/// `wallar calibrate imu-cam` runs.
///
/// For frame pairs (k, k + step) of cam0 whose gyro rotation exceeds a minimum, the camera's
/// rotation from the two images (dsp::camera_rotation_between) is paired with the integrated gyro
/// (dsp::integrate_gyro_rotvec, bias from the first still second when there is one), pairs whose
/// rotation angles disagree are dropped (the angle is the same in both frames), and
/// dsp::solve_R_cam_imu fits the rotation. Camera and IMU clocks are assumed synchronised.
///
/// Threading: plain function on the calling thread.
#pragma once

#include <optional>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/imu/imu_cam_rotation.hpp"
#include "wallar/dsp/imu/visual_rotation.hpp"

namespace wallar::firmware {

struct ImuCamCalibrationParams {
  int frame_step = 2;                   //!< pair frame k with frame k + step
  double min_rotation_deg = 1.0;        //!< pairs turning less say little about the axis
  double max_angle_mismatch_deg = 0.5;  //!< |angle_cam - angle_imu| beyond this: a bad pair
  std::size_t min_pairs = 5;
  double min_axis_spread = 0.1;  //!< ImuCamRotationResult::min_axis_spread needed
  dsp::VisualRotationParams visual;
};

struct ImuCamCalibration {
  dsp::ImuCamRotationResult solved;
  std::size_t frame_pairs = 0;       //!< pairs considered
  std::size_t turning_pairs = 0;     //!< pairs whose gyro turned enough
  std::size_t visual_failures = 0;   //!< too few image matches agreed on a rotation
  std::size_t angle_mismatches = 0;  //!< dropped: camera and gyro angles disagree
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();  //!< removed from the gyro
  bool bias_from_still_window = false;
  /// Angle between the solved rotation and the recording's calibration (cam0 T_BS) [deg].
  double vs_calibration_deg = 0.0;
};

/// Throws InputError naming the recording when there are too few turning pairs, or their
/// rotations all share one axis, so the rotation cannot be determined.
ImuCamCalibration calibrate_imu_cam(const recording::EurocRecording& rec,
                                    const ImuCamCalibrationParams& params = {});

}  // namespace wallar::firmware
