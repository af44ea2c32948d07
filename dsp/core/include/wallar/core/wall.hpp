// SPDX-License-Identifier: Apache-2.0
/// @file wall.hpp
/// @brief A room surface: its plane, its extent and what the estimator saw of it.
///
/// Threading: value types; a WallModel is published as a whole snapshot.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include "wallar/core/plane.hpp"
#include "wallar/core/time.hpp"

namespace wallar {

enum class SurfaceKind : std::uint8_t { kWall, kFloor, kCeiling };

[[nodiscard]] constexpr std::string_view to_string(SurfaceKind kind) {
  switch (kind) {
    case SurfaceKind::kWall:
      return "wall";
    case SurfaceKind::kFloor:
      return "floor";
    case SurfaceKind::kCeiling:
      return "ceiling";
  }
  return "wall";
}

struct Wall {
  std::uint32_t id = 0;  //!< stable across model updates where the wall is matched
  SurfaceKind kind = SurfaceKind::kWall;
  Plane plane;  //!< n toward the room (the viewer's side)
  /// Extent: a closed polygon in the plane, as 2-D coordinates in the basis (u, v) of the
  /// plane with origin `origin` (u x v = n).
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v = Eigen::Vector3d::UnitY();
  std::vector<Eigen::Vector2d> extent_uv_m;
  std::uint32_t inliers = 0;    //!< points within the threshold of the plane
  std::uint32_t backliers = 0;  //!< points behind it, seen from the viewpoints

  /// The extent polygon's corner i in world coordinates.
  [[nodiscard]] Eigen::Vector3d corner(std::size_t i) const {
    return origin + extent_uv_m[i].x() * u + extent_uv_m[i].y() * v;
  }
};

/// The display colour (8-bit RGB) of the surface with this id; the same id, the same colour
/// (point clouds, plots and the headset's overlay agree).
[[nodiscard]] constexpr std::array<std::uint8_t, 3> surface_colour_rgb(std::uint32_t id) {
  constexpr std::array<std::array<std::uint8_t, 3>, 8> kPalette{{{230, 25, 75},
                                                                 {60, 180, 75},
                                                                 {0, 130, 200},
                                                                 {245, 130, 48},
                                                                 {145, 30, 180},
                                                                 {70, 240, 240},
                                                                 {240, 50, 230},
                                                                 {210, 245, 60}}};
  return kPalette[(id - 1) % kPalette.size()];
}

/// The display colour of points on no surface.
inline constexpr std::array<std::uint8_t, 3> kNoSurfaceRgb{128, 128, 128};

/// The room as last estimated.
struct WallModel {
  TimeNs t_ns = 0;            //!< time of the map snapshot it was estimated from
  std::uint64_t version = 0;  //!< increments with each update
  /// The search knew which way is down (2-D: gravity from the IMU or the path), so the kinds
  /// say floor, ceiling and wall. Without it every surface is a kWall of unknown orientation.
  bool gravity_aligned = false;
  std::vector<Wall> walls;
};

}  // namespace wallar
