// SPDX-License-Identifier: Apache-2.0
/// @file pose_estimation.hpp
/// @brief The camera pose from map points seen in the current stereo frame: RANSAC over
/// three-point rigid alignments of the stereo-triangulated points (closed-form absolute
/// orientation, Umeyama), then a robust (Huber) Gauss-Newton refinement of the stereo
/// reprojection error, with outliers re-classified between the passes.
///
/// Threading: free functions, no state. Nothing allocates: the caller owns every buffer.
#pragma once

#include <cstdint>
#include <span>

#include "wallar/core/pose.hpp"
#include "wallar/dsp/tracking/se3.hpp"
#include "wallar/dsp/tracking/stereo_camera.hpp"

namespace wallar::dsp {

/// A map point and where the current frame saw it (rectified pixels).
struct PoseObservation {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  float u_px = 0.0f, v_px = 0.0f;
  float u_right_px = NAN;  //!< NaN when the right eye did not see it
};

struct PoseParams {
  int ransac_iterations = 80;
  double inlier_px = 2.0;       //!< reprojection error of an inlier (each coordinate's norm)
  double huber_px = 1.0;
  int gn_iterations = 8;
  int min_inliers = 12;
};

struct PoseResult {
  SE3d T_cam_world = SE3d::Identity();
  int inliers = 0;
  double rms_px = 0.0;  //!< over the inliers
  bool ok = false;
  bool from_ransac = false;  //!< a RANSAC hypothesis beat the prior
};

/// Squared reprojection error of one observation under T_cam_world (left only or stereo), or
/// infinity when the point is behind the camera.
double reprojection_error_sq(const StereoIntrinsics& K, const SE3d& T_cam_world,
                             const PoseObservation& obs);

/// Robust pose. `prior` is the predicted T_cam_world (motion model or gyro). `inlier` (same
/// length as `observations`) receives 1 for inliers. `seed` makes the sampling repeatable.
PoseResult estimate_pose(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
                         const SE3d& prior, std::span<std::uint8_t> inlier, std::uint64_t seed,
                         const PoseParams& params = {});

/// Gauss-Newton with Huber weights on the observations flagged in `use`, from T; returns the
/// refined pose (unchanged when fewer than 3 observations are usable).
SE3d refine_pose(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
                 std::span<const std::uint8_t> use, SE3d T_cam_world, const PoseParams& params);

}  // namespace wallar::dsp
