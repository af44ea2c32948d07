// SPDX-License-Identifier: Apache-2.0
/// @file imu_cam_calibration.hpp
/// @brief R_cam_imu of a recording's left camera, from the gyro against the images: what
/// `wallar calibrate imu-cam` runs.
///
/// For frame pairs (k, k + step) of cam0 whose gyro rotation exceeds a minimum, the camera's
/// rotation from the two images (dsp::camera_rotation_between) is paired with the integrated gyro
/// (dsp::integrate_gyro_rotvec, bias from the first still second when there is one), pairs whose
/// rotation angles disagree are dropped (the angle is the same in both frames), and
/// dsp::solve_R_cam_imu fits the rotation.
///
/// The camera-IMU time offset (Kalibr's timeshift_cam_imu: t_imu = t_cam + shift) is searched
/// within +-max_time_offset_ms: the gyro is integrated over each pair's window shifted into the
/// IMU's clock, and the shift that best matches the images is kept (first the rotation angles,
/// which do not depend on R, in 0.5 ms steps over the range; then, with R solved there, the
/// rotation vectors in 0.1 ms steps around it; each refined by a parabola; a pair's residual is
/// capped, so a wrong visual rotation cannot pull it). R is solved again at that shift. The
/// offset is observable only while the turn rate changes (a turn's start and end).
///
/// Threading: plain function on the calling thread.
#pragma once

#include <optional>
#include <span>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/imu/imu_cam_rotation.hpp"
#include "wallar/dsp/imu/visual_rotation.hpp"
#include "wallar/firmware/appliance/records.hpp"

namespace wallar::firmware {

struct ImuCamCalibrationParams {
  int frame_step = 2;                   //!< pair frame k with frame k + step
  double min_rotation_deg = 1.0;        //!< pairs turning less say little about the axis
  double max_angle_mismatch_deg = 0.5;  //!< |angle_cam - angle_imu| beyond this: a bad pair
  std::size_t min_pairs = 5;
  double min_axis_spread = 0.1;      //!< ImuCamRotationResult::min_axis_spread needed
  double max_time_offset_ms = 30.0;  //!< the offset searched within +-this; 0: synchronised
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
  /// The camera-IMU time offset found (t_imu = t_cam + shift) [ns]; 0 when not searched.
  std::int64_t timeshift_cam_imu_ns = 0;
  bool time_offset_estimated = false;
  bool from_track = false;  //!< the camera's rotations came from a tracked trajectory
};

/// Throws InputError naming the recording when there are too few turning pairs, or their
/// rotations all share one axis, so the rotation cannot be determined.
ImuCamCalibration calibrate_imu_cam(const recording::EurocRecording& rec,
                                    const ImuCamCalibrationParams& params = {});

/// The same with cam0's rotations taken from a stereo-tracked trajectory of the recording
/// (the appliance run over it vision-only: T_world_body per frame, cam0 at the rig's
/// T_body_cam) instead of from image pairs: tracking against one map has neither the pairwise
/// estimate's noise nor the rotation-only model's bias where the head also moves (a head turns
/// about the neck, its cameras ~10 cm in front). Frames not tracked are left out
/// (visual_failures counts them).
ImuCamCalibration calibrate_imu_cam(const recording::EurocRecording& rec,
                                    std::span<const PoseRecord> trajectory,
                                    const ImuCamCalibrationParams& params = {});

}  // namespace wallar::firmware
