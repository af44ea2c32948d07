// SPDX-License-Identifier: Apache-2.0
/// @file plane.hpp
/// @brief Planes in Hessian normal form n.p - d = 0, n a unit vector toward the viewer.
///
/// The side n points to is the front: a point p is in front when n.p - d > 0. Walls are only
/// seen from the front; points behind a wall (negative distance) are backliers.
///
/// Threading: value type; functions are pure.
#pragma once

#include <Eigen/Core>
#include <optional>

namespace wallar {

struct Plane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  //!< unit normal, toward the front side
  double d = 0.0;                                //!< offset [m]: n.p = d on the plane

  /// Signed distance [m]: positive in front, negative behind.
  [[nodiscard]] double signed_distance(const Eigen::Vector3d& p) const { return n.dot(p) - d; }

  /// The same plane with its front flipped to the other side.
  [[nodiscard]] Plane flipped() const { return Plane{-n, -d}; }

  /// The same plane with its front toward `viewpoint` (unchanged if the viewpoint is on it).
  [[nodiscard]] Plane facing(const Eigen::Vector3d& viewpoint) const {
    return signed_distance(viewpoint) < 0.0 ? flipped() : *this;
  }

  /// The orthogonal projection of p onto the plane.
  [[nodiscard]] Eigen::Vector3d project(const Eigen::Vector3d& p) const {
    return p - signed_distance(p) * n;
  }

  /// The plane through three points, or nothing when they are (nearly) collinear.
  /// The normal follows the right-hand rule (b - a) x (c - a).
  static std::optional<Plane> through(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                      const Eigen::Vector3d& c, double min_area_m2 = 1e-12);
};

/// Angle between two planes' normals [rad], in [0, pi].
double angle_between_rad(const Plane& a, const Plane& b);

}  // namespace wallar
