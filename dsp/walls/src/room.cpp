// SPDX-License-Identifier: Apache-2.0
/// @file room.cpp
/// @brief Sequential wall/floor/ceiling extraction, merging, extents and stable ids.
#include "wallar/dsp/walls/room.hpp"

#include <algorithm>
#include <cmath>

namespace wallar::dsp {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

bool same_plane(const Plane& a, const Plane& b, double angle_rad, double offset_m) {
  return a.n.dot(b.n) > std::cos(angle_rad) && std::abs(a.d - b.d) < offset_m;
}

}  // namespace

BandCounts band_counts(const PointCloud& cloud, const Plane& plane, double threshold_m) {
  const Eigen::Vector3f n = plane.n.cast<float>();
  const auto d = static_cast<float>(plane.d);
  const auto t = static_cast<float>(threshold_m);
  BandCounts c;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const float s = n.x() * cloud.x[i] + n.y() * cloud.y[i] + n.z() * cloud.z[i] - d;
    if (std::abs(s) < t) {
      ++c.on;
    } else if (s >= t && s < 3 * t) {
      ++c.front;
    } else if (s <= -t && s > -3 * t) {
      ++c.behind;
    }
  }
  return c;
}

double BandCounts::excess_sigma() const {
  const double expected = 0.5 * (static_cast<double>(front) + static_cast<double>(behind));
  return (static_cast<double>(on) - expected) / std::sqrt(expected + 1.0);
}

void set_extent(Wall& wall, const std::vector<Eigen::Vector3d>& inliers,
                const std::optional<Eigen::Vector3d>& up) {
  const Eigen::Vector3d& n = wall.plane.n;
  // u horizontal and v up for walls; any orthonormal pair otherwise. u x v = n.
  Eigen::Vector3d v_hint =
      up && std::abs(up->normalized().dot(n)) < 0.9
          ? up->normalized()
          : (std::abs(n.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY());
  wall.v = (v_hint - v_hint.dot(n) * n).normalized();
  wall.u = wall.v.cross(n).normalized();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : inliers) centroid += p;
  if (!inliers.empty()) centroid /= static_cast<double>(inliers.size());
  wall.origin = wall.plane.project(centroid);
  std::vector<Eigen::Vector2d> uv;
  uv.reserve(inliers.size());
  for (const auto& p : inliers) {
    const Eigen::Vector3d q = p - wall.origin;
    uv.emplace_back(q.dot(wall.u), q.dot(wall.v));
  }
  wall.extent_uv_m = convex_hull(std::move(uv));
}

RoomResult RoomEstimator::estimate(const PointCloud& cloud, const RoomConfig& config,
                                   const WallModel* previous) {
  RoomResult result;
  TimeNs t_ns = monotonic_now_ns();
  // Time since the last stamp, and a new stamp.
  const auto lap = [&t_ns] {
    const TimeNs now_ns = monotonic_now_ns();
    const DurationNs dt_ns = now_ns - t_ns;
    t_ns = now_ns;
    return dt_ns;
  };
  detector_.mutable_config() = config.detector;
  detector_.set_points(cloud, config.gravity);
  detector_.set_viewpoints(config.viewpoints);
  detector_.set_manhattan(std::nullopt, 0.0);
  result.points = detector_.size();
  result.skipped_non_finite = detector_.skipped_non_finite();
  const std::optional<Eigen::Vector3d> up =
      config.gravity ? std::optional<Eigen::Vector3d>(-config.gravity->normalized()) : std::nullopt;
  const auto min_inliers = std::max<std::uint32_t>(
      config.min_inliers,
      static_cast<std::uint32_t>(config.min_inlier_fraction * static_cast<double>(result.points)));
  // Scores counted in points (all but B-RANSAC's log score): the searches need not make
  // finding planes that score under min_inliers likely (by kContrast no surface does; by BSF or
  // MSAC, a score at most its inliers, such a plane is at the edge of a surface's size).
  const bool score_in_points = config.detector.method != ScoreMethod::kBinomial;
  detector_.mutable_config().min_score = score_in_points ? min_inliers : 0;
  // By contrast a slab can hold many inliers and score little: its score decides.
  const bool too_small_by_score = config.detector.method == ScoreMethod::kContrast;

  std::vector<Plane> warm_vertical, warm_horizontal, warm_3d;
  if (previous != nullptr) {
    for (const Wall& w : previous->walls) {
      (w.kind == SurfaceKind::kWall ? (up ? warm_vertical : warm_3d) : warm_horizontal)
          .push_back(w.plane);
    }
  }
  bool have_floor = false, have_ceiling = false;
  result.setup_ns = lap();
  DurationNs finish_ns = 0;
  result.searches.reserve(static_cast<std::size_t>(std::max(config.max_surfaces, 0) +
                                                   std::max(config.max_rejected, 0)));
  int rejected = 0;  // candidates that failed the band test
  for (int s = 0; s < config.max_surfaces + rejected; ++s) {
    Detection best;
    RoomSearch& search = result.searches.emplace_back();
    if (up) {
      const Detection wall = detector_.detect_vertical(warm_vertical);
      search.rounds = wall.rounds;
      search.time_ns = lap();
      Detection horizontal;
      if (!(have_floor && have_ceiling)) {
        horizontal = detector_.detect_horizontal(warm_horizontal);
        search.horizontal_rounds = horizontal.rounds;
        search.horizontal_time_ns = lap();
      }
      result.rounds += wall.rounds + horizontal.rounds;
      // Both searches score in the same units; the better surface is taken first. A second
      // floor or ceiling is not accepted.
      const bool h_ok = horizontal.found && !((horizontal.plane.n.dot(*up) > 0 && have_floor) ||
                                              (horizontal.plane.n.dot(*up) < 0 && have_ceiling));
      best = wall;
      if (h_ok && (!wall.found || horizontal.score > wall.score)) best = horizontal;
    } else {
      best = detector_.detect_3d(warm_3d);
      result.rounds += best.rounds;
      search.rounds = best.rounds;
      search.time_ns = lap();
    }
    search.inliers = best.found ? best.inliers : 0;
    if (!best.found || best.inliers < min_inliers ||
        (too_small_by_score && best.score < min_inliers)) {
      search.outcome = best.found ? RoomSearch::Outcome::kTooSmall : RoomSearch::Outcome::kNone;
      break;
    }
    if (config.min_excess_sigma > 0.0) {
      const BandCounts bands = band_counts(cloud, best.plane, config.detector.threshold_m);
      search.excess_sigma = bands.excess_sigma();
      if (search.excess_sigma < config.min_excess_sigma) {
        // Set aside, not reported: the next search may still find a smaller real surface.
        search.outcome = RoomSearch::Outcome::kNotASurface;
        if (++rejected >= config.max_rejected) break;
        detector_.remove_inliers(best.plane);
        continue;
      }
    }

    detector_.remove_inliers(best.plane, &inliers_);
    RoomSurface surface;
    surface.score = best.score;
    surface.rmse_m = best.rmse_m;
    surface.rounds = best.rounds;
    Wall& wall = surface.wall;
    wall.plane = best.plane;
    wall.inliers = best.inliers;
    wall.backliers = best.backliers;
    wall.kind = SurfaceKind::kWall;
    if (up && std::abs(best.plane.n.dot(*up)) > 0.9) {
      // The viewer sees a floor from above: its front (n) points up.
      wall.kind = best.plane.n.dot(*up) > 0 ? SurfaceKind::kFloor : SurfaceKind::kCeiling;
      (wall.kind == SurfaceKind::kFloor ? have_floor : have_ceiling) = true;
    }
    if (config.manhattan && up && wall.kind == SurfaceKind::kWall) {
      // The first wall fixes the room's axes for the walls after it.
      bool first_wall = true;
      for (const auto& other : result.surfaces) first_wall &= other.wall.kind != SurfaceKind::kWall;
      if (first_wall)
        detector_.set_manhattan(wall.plane.n, config.manhattan_tolerance_deg * kDegToRad);
    }
    set_extent(wall, inliers_, up);

    // Merge with a near-duplicate found before (e.g. a wall split by a door).
    bool merged = false;
    for (auto& other : result.surfaces) {
      if (other.wall.kind == wall.kind &&
          same_plane(other.wall.plane, wall.plane, config.merge_angle_deg * kDegToRad,
                     config.merge_offset_m)) {
        std::vector<Eigen::Vector3d> all = inliers_;
        for (std::size_t i = 0; i < other.wall.extent_uv_m.size(); ++i) {
          all.push_back(other.wall.corner(i));
        }
        other.wall.inliers += wall.inliers;
        other.wall.backliers += wall.backliers;
        set_extent(other.wall, all, up);
        merged = true;
        break;
      }
    }
    search.kind = wall.kind;
    search.outcome = merged ? RoomSearch::Outcome::kMerged : RoomSearch::Outcome::kSurface;
    if (!merged) result.surfaces.push_back(std::move(surface));
    finish_ns += lap();  // the surface check, extents and merging
  }

  // Ids: keep the previous model's where a surface matches, new ones otherwise.
  std::uint32_t next_id = 1;
  if (previous != nullptr) {
    for (const Wall& w : previous->walls) next_id = std::max(next_id, w.id + 1);
  }
  std::vector<bool> taken(previous ? previous->walls.size() : 0, false);
  for (auto& s : result.surfaces) {
    s.wall.id = 0;
    if (previous != nullptr) {
      for (std::size_t i = 0; i < previous->walls.size(); ++i) {
        const Wall& w = previous->walls[i];
        if (!taken[i] && w.kind == s.wall.kind &&
            same_plane(w.plane, s.wall.plane, config.id_match_angle_deg * kDegToRad,
                       config.id_match_offset_m)) {
          s.wall.id = w.id;
          taken[i] = true;
          break;
        }
      }
    }
    if (s.wall.id == 0) s.wall.id = next_id++;
    result.model.walls.push_back(s.wall);
  }
  result.model.version = previous != nullptr ? previous->version + 1 : 1;
  result.model.gravity_aligned = config.gravity.has_value();
  result.finish_ns = finish_ns + lap();
  return result;
}

}  // namespace wallar::dsp
