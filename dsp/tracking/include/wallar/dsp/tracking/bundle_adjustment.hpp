// SPDX-License-Identifier: Apache-2.0
/// @file bundle_adjustment.hpp
/// @brief Stereo bundle adjustment for the mapping thread: keyframe poses and 3-D points refined
/// by Levenberg-Marquardt on Huber-weighted reprojection errors in a rectified stereo rig.
///
/// Each Levenberg-Marquardt step solves the normal equations by the Schur complement: the
/// point blocks (3x3 each) are eliminated, the reduced camera system (6 per free keyframe) is
/// solved densely, and the points are back-substituted. Suited to local windows (tens of
/// keyframes, thousands of points); the reduced system is dense.
///
/// Threading: pure functions; no state. Allocates: not for the fixed-rate path.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <span>
#include <vector>

#include "wallar/core/pose.hpp"
#include "wallar/dsp/tracking/se3.hpp"
#include "wallar/dsp/tracking/stereo_camera.hpp"

namespace wallar::dsp {

/// A keyframe: world -> left rectified camera. Fixed keyframes are not moved (they hold the
/// gauge: at least one must be fixed).
struct BaKeyframe {
  SE3d T_cam_world;
  bool fixed = false;
  /// A free keyframe's pose is also pulled toward where it started (its tracked pose) with
  /// these 1-sigma spreads [m, rad] (0: no pull): a keyframe that shares few points with the
  /// others cannot slide along a direction they leave flat (a turn traded for a sideways step).
  double prior_sigma_m = 0.0, prior_sigma_rad = 0.0;
};

struct BaPoint {
  Eigen::Vector3d p_world;
  bool fixed = false;
};

/// One observation of point `point` by keyframe `keyframe`: rectified left pixel (u, v) and right
/// u (u_right), u_right NaN when only the left image saw it (then a 2-D residual).
struct BaObservation {
  int keyframe = 0;
  int point = 0;
  double u_px = 0, v_px = 0, u_right_px = NAN;
  /// The measurement's noise (1 sigma) [px]: residuals and the Huber threshold are in its units
  /// (a key-frame taken in a fast turn, blurred along it, sees its points less precisely).
  double sigma_px = 1.0;
};

struct BaOptions {
  /// Linear solves (accepted or rejected steps): bounds the run time.
  int max_iterations = 10;
  /// Huber threshold on an observation's reprojection error (norm of its 2 or 3 rows) [px].
  double huber_px = 2.0;
  /// Levenberg-Marquardt damping at the start, relative to the normal equations' diagonal.
  double initial_lambda = 1e-4;
  /// Stop when an accepted step lowers the cost by less than this fraction.
  double min_relative_decrease = 1e-6;
};

struct BaResult {
  int iterations = 0;  //!< linear solves done, accepted or rejected
  /// Robust cost 0.5 * sum_obs rho(|r|^2), rho Huber (|r|^2 inside, 2 k |r| - k^2 outside) [px^2].
  double initial_cost = 0, final_cost = 0;
  std::size_t outliers = 0;  //!< observations with error > 3 * huber_px after the adjustment
  bool converged = false;    //!< stopped on a small decrease rather than on max_iterations
  std::size_t observations_used = 0;  //!< observations in front of their camera at the end
};

/// Refines the non-fixed keyframes and points in place so that they agree with `observations`.
/// Throws std::invalid_argument when no keyframe is fixed, when an observation's indices are out
/// of range (naming the observation), or on non-finite measurements / non-positive f_px.
/// Observations whose point lies at depth <= 1e-6 m are skipped in that iteration; a point with
/// fewer than 2 usable residual rows is left unchanged.
BaResult bundle_adjust(const StereoIntrinsics& K, std::vector<BaKeyframe>& keyframes,
                       std::vector<BaPoint>& points, std::span<const BaObservation> observations,
                       const BaOptions& options = {});

// --- Building blocks, public for tests -----------------------------------------------------------

/// Residual (predicted - measured) of one observation with its Jacobians with respect to the left
/// pose perturbation (T_cam_world <- exp(xi) * T_cam_world, xi as in se3_exp) and to p_world.
/// The third row (right u) is zero for a left-only observation.
struct BaLinearization {
  Eigen::Vector3d residual_px = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 3, 6> J_pose = Eigen::Matrix<double, 3, 6>::Zero();
  Eigen::Matrix3d J_point = Eigen::Matrix3d::Zero();
  int rows = 0;  //!< 2 (left only) or 3 (stereo)
};

/// False when the point is at depth <= 1e-6 m in the camera (nothing is written then).
bool linearize_observation(const StereoIntrinsics& K, const SE3d& T_cam_world,
                           const Eigen::Vector3d& p_world, const BaObservation& obs,
                           BaLinearization& out);

}  // namespace wallar::dsp
