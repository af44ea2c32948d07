// SPDX-License-Identifier: Apache-2.0
/// @file camera_yaml.hpp
/// @brief Internal to drivers/recording: the YAML pieces EuRoC's sensor.yaml and Kalibr's
/// camchain share (a rigid transform, a pinhole camera block, the IMU's bias and iron).
///
/// Threading: free functions.
#pragma once

#include <string>
#include <string_view>

#include "wallar/core/calibration.hpp"
#include "wallar/drivers/config/yaml.hpp"

namespace wallar::recording::detail {

/// A 4x4 rigid transform (OpenCV {rows, cols, data}, flat or rows); fails on a rotation part
/// that is not orthonormal with det +1, and on non-finite entries.
SE3d read_rigid(const config::YamlNode& node);

/// camera_model (pinhole), intrinsics [fu, fv, pu, pv], resolution [w, h], distortion_model
/// (radial-tangential/radtan or equidistant) and four coefficients under `distortion_key`
/// ("distortion_coefficients" in EuRoC, "distortion_coeffs" in Kalibr). Every number is
/// checked before use (pixel counts 1..16384, positive finite focal lengths).
CameraCalibration read_pinhole_camera(const config::YamlNode& node,
                                      std::string_view distortion_key);

/// The optional keys `wallar calibrate accel-mag` writes beside an IMU's noise densities
/// (EuRoC's imu0/sensor.yaml and the rig file's imu0 section): accelerometer_bias [3, m/s^2],
/// magnetometer_hard_iron [3, uT], magnetometer_soft_iron [9, row-major]. Each is checked
/// (finite; the soft iron invertible) and fails naming its key.
void read_imu_intrinsics(const config::YamlNode& map, ImuCalibration& imu);

/// Those keys, one per line with `indent` before each, for the values that are not the
/// defaults (zero bias, zero hard iron, identity soft iron): "" when there are none.
std::string format_imu_intrinsics(const ImuCalibration& imu, std::string_view indent);

}  // namespace wallar::recording::detail
