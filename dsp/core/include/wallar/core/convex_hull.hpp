// SPDX-License-Identifier: Apache-2.0
/// @file convex_hull.hpp
/// @brief Convex hull of 2-D points (Andrew's monotone chain), counter-clockwise, without the
/// closing point; wall extents (dsp/walls) and the renderer's clipping polygons (drivers/display).
///
/// Threading: pure functions.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <vector>

namespace wallar {

/// The hull of `points` (sorted and deduplicated in place) into `hull`; fewer than 3 distinct
/// points are returned as they are. Allocates only when `hull` lacks capacity for 2 n points.
inline void convex_hull(std::vector<Eigen::Vector2d>& points, std::vector<Eigen::Vector2d>& hull) {
  std::sort(points.begin(), points.end(), [](const auto& a, const auto& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  points.erase(std::unique(points.begin(), points.end()), points.end());
  if (points.size() < 3) {
    hull.assign(points.begin(), points.end());
    return;
  }
  const auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a,
                        const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  hull.resize(2 * points.size());
  std::size_t k = 0;
  for (const auto& q : points) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], q) <= 0) --k;
    hull[k++] = q;
  }
  for (std::size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
}

/// The same, returning a new vector.
inline std::vector<Eigen::Vector2d> convex_hull(std::vector<Eigen::Vector2d> points) {
  std::vector<Eigen::Vector2d> hull;
  convex_hull(points, hull);
  return hull;
}

}  // namespace wallar
