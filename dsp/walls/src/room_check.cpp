// SPDX-License-Identifier: Apache-2.0
/// @file room_check.cpp
/// @brief Point labels, the floor's free fit against gravity, surface colours.
#include "wallar/dsp/walls/room_check.hpp"

#include <algorithm>
#include <cmath>

#include "wallar/dsp/walls/wall_detector.hpp"

namespace wallar::dsp {

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

double axis_angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::min(angle_deg(a, b), angle_deg(-a, b));
}

std::vector<int> surface_of_points(const PointCloud& cloud, const RoomResult& room,
                                   double threshold_m) {
  std::vector<int> label(cloud.size(), -1);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.point(i).cast<double>();
    for (std::size_t s = 0; s < room.surfaces.size(); ++s) {
      if (std::abs(room.surfaces[s].wall.plane.signed_distance(p)) < threshold_m) {
        label[i] = static_cast<int>(s);
        break;
      }
    }
  }
  return label;
}

std::optional<FloorCheck> check_floor(const PointCloud& cloud, const RoomResult& room,
                                      double threshold_m, const Eigen::Vector3d& up,
                                      const std::optional<Eigen::Vector3d>& up2) {
  const auto floor = std::find_if(room.surfaces.begin(), room.surfaces.end(),
                                  [](const auto& s) { return s.wall.kind == SurfaceKind::kFloor; });
  if (floor == room.surfaces.end()) return std::nullopt;
  std::vector<Eigen::Vector3d> inliers;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.point(i).cast<double>();
    if (std::abs(floor->wall.plane.signed_distance(p)) < threshold_m) inliers.push_back(p);
  }
  const auto free_fit = fit_plane_least_squares(inliers);
  if (!free_fit) return std::nullopt;
  FloorCheck check;
  check.surface = static_cast<std::size_t>(floor - room.surfaces.begin());
  check.distance_below_viewer_m = -floor->wall.plane.d;
  check.inliers = inliers.size();
  check.free_fit = free_fit->facing(Eigen::Vector3d::Zero());
  check.free_fit_vs_up_deg = axis_angle_deg(free_fit->n, up);
  if (up2) check.free_fit_vs_up2_deg = axis_angle_deg(free_fit->n, *up2);
  return check;
}

}  // namespace wallar::dsp
