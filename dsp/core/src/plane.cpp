// SPDX-License-Identifier: Apache-2.0
/// @file plane.cpp
/// @brief Plane construction from points.
#include "wallar/core/plane.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace wallar {

std::optional<Plane> Plane::through(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, double min_area_m2) {
  const Eigen::Vector3d cross = (b - a).cross(c - a);
  const double norm = cross.norm();
  // |cross| is twice the triangle's area: reject degenerate (collinear) samples.
  if (!(norm > 2.0 * min_area_m2)) return std::nullopt;
  Plane plane;
  plane.n = cross / norm;
  plane.d = plane.n.dot(a);
  return plane;
}

double angle_between_rad(const Plane& a, const Plane& b) {
  return std::acos(std::clamp(a.n.dot(b.n), -1.0, 1.0));
}

}  // namespace wallar
