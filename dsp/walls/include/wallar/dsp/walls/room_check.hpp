// SPDX-License-Identifier: Apache-2.0
/// @file room_check.hpp
/// @brief An estimated room held against its own points and against gravity: which surface
/// each point lies on, the floor's orientation fitted freely in 3-D on its inliers compared
/// with an "up" direction (IMU or ground truth), angle helpers, and the display colour of a
/// surface. Shared by `wallar run` and `wallar eval real`.
///
/// Threading: pure functions; no state.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "wallar/core/point_cloud.hpp"
#include "wallar/dsp/walls/room.hpp"

namespace wallar::dsp {

/// Angle between the directions a and b [deg], in [0, 180].
double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

/// Angle between the lines along a and b [deg], in [0, 90] (a fitted normal has no sign).
double axis_angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

/// For each point of `cloud`, the index into room.surfaces of the first surface (in order of
/// discovery) within threshold_m of it, or -1 when it lies on none.
std::vector<int> surface_of_points(const PointCloud& cloud, const RoomResult& room,
                                   double threshold_m);

/// The floor's own orientation: its inliers (|distance| < threshold_m) fitted by least squares
/// without the gravity constraint the room search used, compared with "up".
struct FloorCheck {
  std::size_t surface = 0;               //!< index into RoomResult::surfaces
  double distance_below_viewer_m = 0.0;  //!< -d of the (gravity-aligned) floor plane
  std::size_t inliers = 0;               //!< points the free fit used
  Plane free_fit;                        //!< n toward the viewer
  double free_fit_vs_up_deg = 0.0;       //!< axis angle between free_fit.n and `up`
  /// Axis angle between free_fit.n and a second "up" (e.g. ground truth), when given.
  std::optional<double> free_fit_vs_up2_deg;
};

/// Checks the first floor of `room` (points and planes in the same frame, the viewer at the
/// origin). Returns nothing when the room has no floor or its inliers admit no fit.
std::optional<FloorCheck> check_floor(const PointCloud& cloud, const RoomResult& room,
                                      double threshold_m, const Eigen::Vector3d& up,
                                      const std::optional<Eigen::Vector3d>& up2 = std::nullopt);

// The surfaces' display colours live beside Wall (wallar/core/wall.hpp).
using wallar::kNoSurfaceRgb;
using wallar::surface_colour_rgb;

}  // namespace wallar::dsp
