// SPDX-License-Identifier: Apache-2.0
/// @file metrics.cpp
/// @brief Eq. 3.6 and the plane error behind the success criterion.
#include "wallar/dsp/eval/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace wallar::dsp {

double projected_inlier_rmse(std::span<const Eigen::Vector3d> inliers, const Plane& estimated,
                             const Plane& truth) {
  if (inliers.empty()) return 0.0;
  double sum_sq = 0.0;
  for (const Eigen::Vector3d& p : inliers) {
    const Eigen::Vector3d projected = estimated.project(p);
    const double dist = truth.signed_distance(projected);
    sum_sq += dist * dist;
  }
  return std::sqrt(sum_sq / static_cast<double>(inliers.size()));
}

PlaneError plane_error(const Plane& estimated, const Plane& truth) {
  const double cos_angle = std::clamp(std::abs(estimated.n.dot(truth.n)), 0.0, 1.0);
  const Eigen::Vector3d foot = truth.n * truth.d;
  return PlaneError{std::acos(cos_angle) * 180.0 / M_PI, std::abs(estimated.signed_distance(foot))};
}

std::string SuccessCriterion::describe() const {
  char buf[128];
  std::snprintf(buf, sizeof buf, "normal within %g deg and offset within %g m of the true wall",
                max_angle_deg, max_offset_m);
  return buf;
}

}  // namespace wallar::dsp
