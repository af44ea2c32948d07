// SPDX-License-Identifier: Apache-2.0
/// @file room.hpp
/// @brief The room model: walls, floor and ceiling found one after another (thesis §5.2).
///
/// Each found surface's inliers are removed before the next search. With gravity, walls are
/// vertical planes (2-D search) and floor/ceiling horizontal ones (normal parallel to gravity,
/// the floor below the viewpoints, the ceiling above); without, every surface is a 3-D wall.
/// Optionally walls are kept Manhattan (parallel or perpendicular to the first within a
/// tolerance). Near-duplicate planes are merged. Each surface gets an extent polygon (the
/// convex hull of its inliers in its own plane) and an id that stays the same across updates
/// where a surface matches one of the previous model (the previous planes also warm-start the
/// search).
///
/// Threading: one RoomEstimator per thread.
#pragma once

#include <optional>
#include <vector>

#include "wallar/core/convex_hull.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"

namespace wallar::dsp {

struct RoomConfig {
  DetectorConfig detector;
  std::optional<Eigen::Vector3d> gravity;  //!< "down" in the cloud's frame; enables 2-D mode
  std::vector<Eigen::Vector3d> viewpoints{Eigen::Vector3d::Zero()};
  int max_surfaces = 6;
  std::uint32_t min_inliers = 12;     //!< smaller surfaces are not reported
  double min_inlier_fraction = 0.02;  //!< ... nor those under this share of the points
  bool manhattan = false;
  double manhattan_tolerance_deg = 5.0;
  double merge_angle_deg = 5.0;
  double merge_offset_m = 0.1;
  double id_match_angle_deg = 10.0;  //!< a surface keeps a previous id within these
  double id_match_offset_m = 0.25;
};

struct RoomSurface {
  Wall wall;
  double score = 0.0;
  double rmse_m = 0.0;
  std::uint32_t rounds = 0;
};

struct RoomResult {
  WallModel model;
  std::vector<RoomSurface> surfaces;  //!< same order as model.walls
  std::uint32_t rounds = 0;           //!< all searches together
  std::size_t points = 0;             //!< finite points searched
  std::size_t skipped_non_finite = 0;
};

class RoomEstimator {
 public:
  explicit RoomEstimator(std::size_t max_points) : detector_(max_points, {}) {}

  /// Estimates the room from `cloud`; `previous` (may be null) warm-starts and supplies ids.
  RoomResult estimate(const PointCloud& cloud, const RoomConfig& config,
                      const WallModel* previous = nullptr);

 private:
  WallDetector detector_;
  std::vector<Eigen::Vector3d> inliers_;
};

/// The search for a tracker's sparse map: the inlier band `threshold_m`, the key-frames' centres
/// as the viewpoints of the backlier test (the origin when there are none; evenly spaced ones
/// when there are more than the detector holds, a moving rig's path), 2-D with `down`
/// (gravity in the map's frame) when given, 3-D otherwise.
inline RoomConfig room_config_for_map(const std::vector<Eigen::Vector3d>& keyframe_centres,
                                      const std::optional<Eigen::Vector3d>& down,
                                      double threshold_m, int max_surfaces = 6) {
  RoomConfig config;
  config.detector.threshold_m = threshold_m;
  config.gravity = down;
  const std::size_t n = keyframe_centres.size();
  if (n <= kMaxViewpoints) {
    config.viewpoints = keyframe_centres;
  } else {
    config.viewpoints.clear();  // the default holds the origin
    for (std::size_t i = 0; i < kMaxViewpoints; ++i) {
      config.viewpoints.push_back(keyframe_centres[i * (n - 1) / (kMaxViewpoints - 1)]);
    }
  }
  if (config.viewpoints.empty()) config.viewpoints.push_back(Eigen::Vector3d::Zero());
  config.max_surfaces = max_surfaces;
  return config;
}

// Convex hull of 2-D points: wallar/core/convex_hull.hpp (shared with the renderer).
using wallar::convex_hull;

/// Fills wall.origin/u/v/extent_uv_m from the wall's inliers (u horizontal when `up` is given).
void set_extent(Wall& wall, const std::vector<Eigen::Vector3d>& inliers,
                const std::optional<Eigen::Vector3d>& up);

}  // namespace wallar::dsp
