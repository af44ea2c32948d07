// SPDX-License-Identifier: Apache-2.0
/// @file accel_mag_calibration.hpp
/// @brief The accelerometer's bias and the magnetometer's hard and soft iron from a recording
/// of the headset held still in several tilts and turned round (dsp/imu/imu_intrinsics.hpp):
/// what `wallar calibrate accel-mag` runs. The result goes into an imu0/sensor.yaml beside the
/// noise densities, which `calibrate imu-cam --imu` carries into the rig file and the attitude
/// filter applies to every sample. Where the recording has ground truth (a synth-rig one), it
/// is checked against it.
///
/// Threading: plain function on the calling thread.
#pragma once

#include <optional>
#include <vector>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/imu/imu_intrinsics.hpp"

namespace wallar::firmware {

struct AccelMagCalibrationParams {
  double gravity_m_s2 = 9.81;  //!< the local gravity the still poses are held to
  double field_uT = 0.0;       //!< the local field strength; 0: the sensor's own scale
  dsp::StillPoseParams still;
};

struct AccelMagCalibration {
  double duration_s = 0.0;
  std::size_t samples = 0;
  std::size_t mag_samples = 0;  //!< IMU samples that carry a magnetometer reading
  std::vector<dsp::StillPose> poses;
  dsp::AccelBiasFit accel;
  std::optional<dsp::MagnetometerFit> mag;  //!< when the recording has magnetometer readings

  /// With ground truth: the truth's accelerometer bias averaged over the poses.
  std::optional<Eigen::Vector3d> accel_bias_truth_m_s2;
  /// With ground truth: RMS over the poses of the angle between the accelerometer's "up" and
  /// the truth's, as read and with the bias removed [deg].
  std::optional<double> tilt_error_raw_deg, tilt_error_deg;
  /// With ground truth and a magnetometer: the circular standard deviation of the field's
  /// world heading over the readings (0 for a perfect sensor in a clean field), as read and
  /// corrected [deg].
  std::optional<double> heading_spread_raw_deg, heading_spread_deg;
};

/// Throws InputError naming the recording when it has no IMU samples. A fit that cannot be
/// solved (too few still poses, tilts or orientations) comes back unsolved, for the command to
/// say why.
AccelMagCalibration calibrate_accel_mag(const recording::EurocRecording& rec,
                                        const AccelMagCalibrationParams& params = {});

}  // namespace wallar::firmware
