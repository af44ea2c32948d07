// SPDX-License-Identifier: Apache-2.0
/// @file room.hpp
/// @brief The room model: walls, floor and ceiling found one after another (thesis §5.2).
///
/// Each found surface's inliers are removed before the next search, which ends at the first
/// candidate that is too small. Optionally (RoomConfig::min_excess_sigma) a candidate no denser
/// than the space beside it (a slab through scattered clutter, BandCounts) is not reported. With
/// gravity, walls are vertical planes (2-D search) and floor/ceiling horizontal ones (normal
/// parallel to gravity, the floor below the viewpoints, the ceiling above); without, every surface
/// is a 3-D wall. Optionally walls are kept Manhattan (parallel or perpendicular to the first
/// within a tolerance). Near-duplicate planes are merged. Each surface gets an extent polygon (the
/// convex hull of its inliers in its own plane) and an id that stays the same across updates
/// where a surface matches one of the previous model (the previous planes also warm-start the
/// search).
///
/// Threading: one RoomEstimator per thread.
#pragma once

#include <optional>
#include <vector>

#include "wallar/core/convex_hull.hpp"
#include "wallar/core/time.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"

namespace wallar::dsp {

struct RoomConfig {
  /// BSF (the DetectorConfig default), not kContrast: a tracker's map points scatter across
  /// the whole band (far ones more), where the band's halves are equally full and a contrast
  /// says nothing; on the street clip's map the facades were lost by contrast (docs/perf.md).
  /// Each search stops at its confidence or at a budget of 20,000 rounds: the last search, the
  /// one that finds nothing, would otherwise run (in 3-D, in dense clutter) 50,000 - 200,000
  /// rounds to rule out a surface at min_inlier_fraction.
  DetectorConfig detector{.max_rounds = 20'000};
  std::optional<Eigen::Vector3d> gravity;  //!< "down" in the cloud's frame; enables 2-D mode
  std::vector<Eigen::Vector3d> viewpoints{Eigen::Vector3d::Zero()};
  int max_surfaces = 6;
  /// A surface has at least this many inliers (kContrast: scores at least this), else it is not
  /// reported and the search ends.
  std::uint32_t min_inliers = 12;
  double min_inlier_fraction = 0.015;  //!< ... and at least this share of the points
  bool manhattan = false;
  double manhattan_tolerance_deg = 5.0;
  /// Opt-in (0: off, the default): a surface is denser than the space beside it. Its inlier
  /// band must hold more points than the mean of the two bands of the same width beside it (in
  /// front, behind) by this many standard deviations (Poisson; 4 is the tested value), else it
  /// is a slab of scattered points, not a surface: it is not reported. On uniform clutter this
  /// removes the slabs reported as walls and most of the time; it also loses thin real
  /// surfaces behind clumped clutter and some of a street map's facades (docs/perf.md), so the
  /// sequential search keeps the thesis's rule by default.
  double min_excess_sigma = 0.0;
  /// With the test on: candidates that fail it before the search ends; each one's inliers are
  /// set aside (not reported), so a smaller real surface behind a slab may still be found.
  int max_rejected = 1;
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

/// One pass of the sequential search, for the time report: where a detection's time goes.
struct RoomSearch {
  enum class Outcome : std::uint8_t {
    kSurface,      //!< a new surface
    kMerged,       //!< merged into one found before
    kTooSmall,     //!< the best candidate had fewer inliers than a surface needs: the search ends
    kNotASurface,  //!< no denser than beside it: set aside (the search ends at max_rejected)
    kNone,         //!< no candidate at all: the search ends
  };
  Outcome outcome = Outcome::kNone;
  std::uint32_t rounds = 0;             //!< the wall search's (3-D or vertical)
  DurationNs time_ns = 0;               //!< the wall search's
  std::uint32_t horizontal_rounds = 0;  //!< 2-D: the floor/ceiling search's (0: not run)
  DurationNs horizontal_time_ns = 0;
  std::uint32_t inliers = 0;  //!< the best candidate's
  double excess_sigma = 0.0;  //!< its points beyond those beside it (BandCounts), if checked
  SurfaceKind kind = SurfaceKind::kWall;  //!< meaningful when it found a surface

  /// A surface came of it (new or merged into one found before).
  [[nodiscard]] bool found_surface() const {
    return outcome == Outcome::kSurface || outcome == Outcome::kMerged;
  }
};

/// Points of a cloud in three slabs of width 2t along a plane: its inlier band (-t, t), and
/// beside it in front [t, 3t) and behind (-3t, -t].
struct BandCounts {
  std::uint32_t behind = 0, on = 0, front = 0;
  /// How far the band's count is above the mean of its neighbours', in standard deviations of
  /// that mean as a Poisson count: a surface stands out, a slab of scattered points does not.
  [[nodiscard]] double excess_sigma() const;
};
BandCounts band_counts(const PointCloud& cloud, const Plane& plane, double threshold_m);
[[nodiscard]] constexpr const char* to_string(RoomSearch::Outcome o) {
  switch (o) {
    case RoomSearch::Outcome::kSurface:
      return "surface";
    case RoomSearch::Outcome::kMerged:
      return "merged";
    case RoomSearch::Outcome::kTooSmall:
      return "too small";
    case RoomSearch::Outcome::kNotASurface:
      return "not a surface";
    case RoomSearch::Outcome::kNone:
      return "none";
  }
  return "?";
}

struct RoomResult {
  WallModel model;
  std::vector<RoomSurface> surfaces;  //!< same order as model.walls
  std::uint32_t rounds = 0;           //!< all searches together
  std::size_t points = 0;             //!< finite points searched
  std::size_t skipped_non_finite = 0;
  /// Time per stage (CLOCK_MONOTONIC): loading the points, each search in turn (the last one
  /// finds no surface, unless max_surfaces ended it), the surface checks, extents, merges and
  /// ids (`finish_ns`).
  DurationNs setup_ns = 0;
  std::vector<RoomSearch> searches;
  DurationNs finish_ns = 0;
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
