// SPDX-License-Identifier: Apache-2.0
/// @file visual_rotation.hpp
/// @brief The camera's rotation between two images of one camera: ORB features matched both
/// ways, undistorted to bearings, and a rotation-only model fitted by RANSAC (Kabsch on
/// two bearings per hypothesis) then refined on the inliers.
///
/// The rotation-only model holds when the camera moves little between the two images compared
/// with the distance to the scene (a head over 100 ms: millimetres against metres); the
/// essential matrix, the general model, is degenerate exactly in that case.
///
/// Threading: pure function; no state. Allocates (OpenCV): not for the fixed-rate path.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>

#include "wallar/core/calibration.hpp"
#include "wallar/core/image.hpp"

namespace wallar::dsp {

struct VisualRotationParams {
  int max_corners = 1000;            //!< ORB features per image
  double inlier_threshold_px = 1.5;  //!< bearing error, converted with fx
  int ransac_rounds = 200;
  std::size_t min_inliers = 30;
  std::uint64_t seed = 1;
};

struct VisualRotation {
  /// Rotation of the camera from image 0 to image 1, as a rotation vector in the camera frame at
  /// image 0: R_cam0_cam1 = Exp(rotvec_cam0_cam1).
  Eigen::Vector3d rotvec_cam0_cam1 = Eigen::Vector3d::Zero();
  std::size_t tracked = 0;  //!< features matched between the images
  std::size_t inliers = 0;
  double rms_error_px = 0.0;  //!< inliers' bearing error, times fx
};

/// Nothing when too few corners are tracked or agree (`min_inliers`). Gray 8-bit images of the
/// calibration's size; radial-tangential distortion is removed (an empty distortion means none).
std::optional<VisualRotation> camera_rotation_between(const Image& image0, const Image& image1,
                                                      const CameraCalibration& cam,
                                                      const VisualRotationParams& params = {});

}  // namespace wallar::dsp
