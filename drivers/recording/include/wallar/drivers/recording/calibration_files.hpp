// SPDX-License-Identifier: Apache-2.0
/// @file calibration_files.hpp
/// @brief Stereo rig calibrations on disk: OpenCV stereo YAML and Kalibr camchain YAML
/// (written and read), and EuRoC folders (read).
///
/// OpenCV stereo YAML (cv::FileStorage format, as OpenCV's stereo_calib sample writes it):
///   image_width, image_height, K1, D1, K2, D2 (intrinsics, distortion k1 k2 p1 p2 [k3]),
///   R, T (x_right = R x_left + T), plus whatever extra matrices the writer is given (R1, R2,
///   P1, P2, Q of the rectification). M1/M2 are accepted for K1/K2 (OpenCV's older names).
/// Kalibr camchain YAML: cam0, cam1 with camera_model pinhole, intrinsics [fu, fv, pu, pv],
///   distortion_model radtan (or equidistant), distortion_coeffs, resolution [w, h], cam1's
///   T_cn_cnm1 (= T_cam1_cam0), and T_cam_imu when the IMU is calibrated too; wallar adds each
///   camera's `rate_hz` when known (Kalibr's readers ignore the key).
/// Rigs read from files without an IMU use the left camera as the body frame, and say so
/// (RigCalibration::imu_extrinsic_known false) unless the file has `imu_aligned_with_cam0: true`.
///
/// Threading: free functions.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "wallar/core/calibration.hpp"

namespace wallar::recording {

/// Named matrices appended to an OpenCV YAML file (e.g. "R1", the rectification).
using ExtraMatrices = std::vector<std::pair<std::string, Eigen::MatrixXd>>;

std::string format_opencv_stereo_yaml(const RigCalibration& rig, const ExtraMatrices& extra = {});
/// Throws InputError when a camera's distortion cannot be written as Kalibr's radtan (k3 != 0).
/// with_imu: each camera's T_cam_imu and timeshift_cam_imu, and, when the IMU's noise is known,
/// an `imu0:` section in Kalibr's imu.yaml names (the rig file `wallar calibrate` writes; the
/// reader takes it back).
std::string format_kalibr_camchain(const RigCalibration& rig, bool with_imu = false);

/// Parses an OpenCV stereo YAML or a Kalibr camchain (told apart by their keys); errors name
/// `name`, the line and the key.
RigCalibration parse_rig_calibration(std::string_view text, const std::string& name);
/// A EuRoC folder (ROOT or ROOT/mav0: cam0/cam1 sensor.yaml, imu0/sensor.yaml when present) or
/// a file parse_rig_calibration() reads. Throws InputError naming the path.
RigCalibration read_rig_calibration(const std::filesystem::path& path);

}  // namespace wallar::recording
