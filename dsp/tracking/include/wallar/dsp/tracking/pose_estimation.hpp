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
  float sigma_m = 0.0f;    //!< the map point's position uncertainty (1 sigma, along the ray)
  /// How much the observation counts in the refinement (a far point's bearing: its depth, from
  /// one small disparity, would otherwise steer the translation).
  float weight = 1.0f;
};

struct PoseParams {
  int ransac_iterations = 80;
  double inlier_px = 2.0;  //!< reprojection error of an inlier (each coordinate's norm)
  double huber_px = 1.0;
  int gn_iterations = 8;
  int min_inliers = 12;
  /// Scale of the Cauchy pass over every observation that starts each polish [px]: a predicted
  /// pose this far off is still pulled into place.
  double wide_px = 6.0;
  /// RANSAC hypotheses are scored with inlier_px times this (three points fix a pose roughly).
  double hypothesis_radius_factor = 2.5;
  /// Points sampled for a hypothesis need at least this disparity (a usable depth) [px].
  double min_sample_disparity_px = 1.0;
  /// Disparity measurement noise (1 sigma) [px]; with the map point's depth uncertainty it sets
  /// how much the disparity residual counts (the stereo row of a far point weighs little).
  double disparity_sigma_px = 0.5;
  /// A rotation the pose should keep, R_cam_world (the gyro's prediction): the refinements add
  /// the residual log(R R_prior^T) with this weight [px^2 / rad^2] (0: no such term). Where
  /// vision cannot tell a turn from a sideways step (motion blur along the turn), the gyro can.
  double rotation_prior_weight = 0.0;
  Eigen::Matrix3d R_prior_cw = Eigen::Matrix3d::Identity();
};

struct PoseResult {
  SE3d T_cam_world = SE3d::Identity();
  int inliers = 0;
  double rms_px = 0.0;  //!< over the inliers
  bool ok = false;
  bool from_ransac = false;  //!< a RANSAC hypothesis beat the prior
};

/// Squared reprojection error of one observation under T_cam_world, or infinity when the point
/// is behind the camera: the left image's (u, v) error plus, with a right match, the disparity
/// error weighted by disparity_weight().
double reprojection_error_sq(const StereoIntrinsics& K, const SE3d& T_cam_world,
                             const PoseObservation& obs, double disparity_sigma_px = 0.5);
/// How much an observation's disparity residual counts (0..1]: the disparity noise against the
/// noise plus what the map point's depth uncertainty (obs.sigma_m at depth_m) moves it by.
double disparity_weight(const StereoIntrinsics& K, const PoseObservation& obs, double depth_m,
                        double sigma_px);

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
