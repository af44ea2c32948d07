// SPDX-License-Identifier: Apache-2.0
/// @file metrics.hpp
/// @brief The thesis's evaluation measures (§3.4): accuracy as the RMSE of the inliers, projected
/// onto the estimated plane, against the ground-truth plane (eq. 3.6), and robustness as
/// successes over trials (eq. 3.7), with "success" spelled out (SuccessCriterion).
///
/// Threading: pure functions and value types.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string>

#include "wallar/core/plane.hpp"

namespace wallar::dsp {

/// Eq. 3.6: each inlier p is first moved onto the estimated plane (p' = p - n_e((p0_e - p).n_e),
/// so its scatter across the estimate does not count), then the RMS of the distances of the p'
/// to the ground-truth plane. 0 for no inliers.
double projected_inlier_rmse(std::span<const Eigen::Vector3d> inliers, const Plane& estimated,
                             const Plane& truth);

/// How far an estimated plane is from the truth: the angle between their normals (either sign,
/// a fitted normal's sign is a convention) and the distance from the estimated plane to the
/// truth's foot point (its point nearest the origin, the viewpoint of the thesis's scenes).
struct PlaneError {
  double angle_deg = 0.0;
  double offset_m = 0.0;
};
PlaneError plane_error(const Plane& estimated, const Plane& truth);

/// A detection succeeds when its normal is within max_angle_deg of the truth's and its offset
/// (PlaneError::offset_m) within max_offset_m.
struct SuccessCriterion {
  double max_angle_deg = 5.0;
  double max_offset_m = 0.1;
  [[nodiscard]] bool success(const PlaneError& e) const {
    return e.angle_deg <= max_angle_deg && e.offset_m <= max_offset_m;
  }
  /// "normal within 5 deg and offset within 0.1 m of the true wall"
  [[nodiscard]] std::string describe() const;
};

/// Eq. 3.7: N_success / N_trials.
struct Robustness {
  std::uint32_t successes = 0;
  std::uint32_t trials = 0;
  void add(bool success) {
    ++trials;
    if (success) ++successes;
  }
  /// 0 when there were no trials.
  [[nodiscard]] double value() const {
    return trials == 0 ? 0.0 : static_cast<double>(successes) / static_cast<double>(trials);
  }
};

}  // namespace wallar::dsp
