// SPDX-License-Identifier: Apache-2.0
/// @file camera_yaml.hpp
/// @brief Internal to drivers/recording: the YAML pieces EuRoC's sensor.yaml and Kalibr's
/// camchain share (a rigid transform, a pinhole camera block).
///
/// Threading: free functions.
#pragma once

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

}  // namespace wallar::recording::detail
