// SPDX-License-Identifier: Apache-2.0
/// @file trajectory.hpp
/// @brief Trajectory accuracy against ground truth: absolute trajectory error (ATE) after a
/// rigid alignment and relative pose error (RPE) over a fixed time span, as in the TUM RGB-D
/// benchmark (Sturm et al. 2012).
///
/// Threading: pure functions and value types.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <span>

#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"

namespace wallar::dsp {

struct TrajectoryErrors {
  std::size_t matched = 0;           //!< estimates with a ground-truth pose at their time
  double path_length_m = 0;          //!< length of the matched ground-truth positions' polyline
  double ate_rmse_m = 0;             //!< RMS of |T_gt_est * p_est - p_gt| over the matched poses
  double ate_max_m = 0;              //!< largest of those distances
  double rpe_trans_rmse_m = 0;       //!< RMS translation of the relative-pose errors
  double rpe_rot_rmse_deg = 0;       //!< RMS rotation angle of the relative-pose errors
  double rpe_delta_s = 0;            //!< mean time span of the RPE pairs used (0: no pair)
  std::size_t rpe_pairs = 0;         //!< number of RPE pairs
  SE3d T_gt_est = SE3d::Identity();  //!< the alignment applied to the estimate (identity if off)
};

struct TrajectoryEvalOptions {
  /// An estimate is matched when the ground-truth samples bracketing its time are each within
  /// max_dt_ns of it (an exact time match needs only that sample).
  TimeNs max_dt_ns = 20'000'000;
  /// RPE time span [s]: each matched pose i is paired with the later matched pose j whose
  /// t_j - t_i is nearest to it, when that is within (strictly) 5 % of rpe_delta_s.
  double rpe_delta_s = 1.0;
  /// Align the estimate onto the ground truth (SE(3) Umeyama, no scale) before the ATE.
  bool align = true;
};

/// Compares `est` with `gt`, both sorted by t_ns (T_world_body each). Each estimate is matched
/// to gt interpolated at its time (translation lerp, rotation slerp) when gt brackets it within
/// max_dt_ns; unmatched estimates are skipped. ATE: RMS of the translation differences after
/// aligning est onto gt (T_gt_est, identity when options.align is false). RPE over pairs (i, j)
/// with t_j - t_i ~ rpe_delta_s: E = (gt_i^-1 gt_j)^-1 (est_i^-1 est_j), RMS of |E.t| and of the
/// angle of E.R (alignment-independent). Throws std::invalid_argument when fewer than 3
/// estimates match, when either input is not sorted, or for bad options.
TrajectoryErrors evaluate_trajectory(std::span<const StampedPose> est,
                                     std::span<const StampedPose> gt,
                                     const TrajectoryEvalOptions& options = {});

/// The rigid transform (rotation + translation, no scale) that best maps `from` onto `to` in
/// least squares (Umeyama 1991 / Kabsch; a proper rotation, never a reflection). Throws
/// std::invalid_argument when the spans differ in size or hold fewer than 3 points.
SE3d align_rigid(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to);

}  // namespace wallar::dsp
