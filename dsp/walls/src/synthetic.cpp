// SPDX-License-Identifier: Apache-2.0
/// @file synthetic.cpp
/// @brief Labelled synthetic scenes for tests, evaluation and benchmarks.
#include "wallar/dsp/walls/synthetic.hpp"

#include <cmath>
#include <random>

namespace wallar::dsp {
namespace {

class Scene {
 public:
  explicit Scene(std::uint64_t seed) : rng_(seed) {}
  double uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }
  void add(double x, double y, double z, PointLabel label) {
    out.cloud.push_back(
        Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)));
    out.labels.push_back(label);
  }
  LabelledCloud out;

 private:
  std::mt19937_64 rng_;
};

}  // namespace

LabelledCloud make_thesis_scene(const ThesisSceneParams& p) {
  Scene s(p.seed);
  const double half = p.noise_m / 2;
  const double w = p.wall_size_m / 2;
  for (std::size_t i = 0; i < p.wall_points; ++i) {
    s.add(s.uniform(-w, w), s.uniform(-w, w), p.wall_distance_m + s.uniform(-half, half),
          PointLabel::kWall);
  }
  const double q = p.plane_size_m / 2;
  for (std::size_t i = 0; i < p.plane_points; ++i) {
    s.add(s.uniform(-q, q), s.uniform(-q, q), p.plane_distance_m + s.uniform(-half, half),
          PointLabel::kFrontPlane);
  }
  const double rho = std::clamp(p.rho_b, 0.0, 0.95);
  const auto backliers =
      static_cast<std::size_t>(std::lround(rho / (1.0 - rho) * static_cast<double>(p.wall_points)));
  for (std::size_t i = 0; i < backliers; ++i) {
    s.add(s.uniform(-w, w), s.uniform(-w, w),
          p.wall_distance_m + half + s.uniform(0.0, p.backlier_depth_m), PointLabel::kBacklier);
  }
  for (std::size_t i = 0; i < p.outliers; ++i) {
    s.add(s.uniform(-w, w), s.uniform(-w, w), s.uniform(0.1, p.wall_distance_m - half),
          PointLabel::kOutlier);
  }
  s.out.wall = Plane{-Eigen::Vector3d::UnitZ(), -p.wall_distance_m};
  return std::move(s.out);
}

LabelledCloud make_sparse_map(const SparseMapParams& p) {
  Scene s(p.seed);
  const double half = p.noise_m / 2;
  const auto wall =
      static_cast<std::size_t>(std::lround(p.wall_fraction * static_cast<double>(p.points)));
  const double rho = std::clamp(p.rho_b, 0.0, 0.95);
  const auto back =
      static_cast<std::size_t>(std::lround(rho / (1.0 - rho) * static_cast<double>(wall)));
  for (std::size_t i = 0; i < wall; ++i) {
    s.add(s.uniform(-2.0, 2.0), s.uniform(-1.5, 1.5), p.wall_distance_m + s.uniform(-half, half),
          PointLabel::kWall);
  }
  for (std::size_t i = 0; i < back && wall + i < p.points; ++i) {
    s.add(s.uniform(-2.0, 2.0), s.uniform(-1.5, 1.5),
          p.wall_distance_m + half + s.uniform(0.0, 1.0), PointLabel::kBacklier);
  }
  while (s.out.cloud.size() < p.points) {
    s.add(s.uniform(-2.0, 2.0), s.uniform(-1.5, 1.5), s.uniform(0.5, p.wall_distance_m - half),
          PointLabel::kOutlier);
  }
  s.out.wall = Plane{-Eigen::Vector3d::UnitZ(), -p.wall_distance_m};
  return std::move(s.out);
}

LabelledCloud make_room_scene(const RoomSceneParams& p) {
  Scene s(p.seed);
  const double hw = p.width_m / 2, hd = p.depth_m / 2, h = p.noise_m / 2;
  const double top = -p.ceiling_above_m, bottom = p.floor_below_m;  // y is down
  const std::size_t n = p.points_per_surface;
  auto& surf = s.out.surfaces;
  // Walls first (front z+, then right x+, back z-, left x-), then floor and ceiling; each
  // normal points into the room, toward the viewpoint at the origin.
  for (std::size_t i = 0; i < n; ++i)
    s.add(s.uniform(-hw, hw), s.uniform(top, bottom), hd + s.uniform(-h, h), PointLabel::kWall);
  surf.push_back({-Eigen::Vector3d::UnitZ(), -hd});
  for (std::size_t i = 0; i < n; ++i)
    s.add(hw + s.uniform(-h, h), s.uniform(top, bottom), s.uniform(-hd, hd),
          PointLabel::kOtherWall);
  surf.push_back({-Eigen::Vector3d::UnitX(), -hw});
  for (std::size_t i = 0; i < n; ++i)
    s.add(s.uniform(-hw, hw), s.uniform(top, bottom), -hd + s.uniform(-h, h),
          PointLabel::kOtherWall);
  surf.push_back({Eigen::Vector3d::UnitZ(), -hd});
  for (std::size_t i = 0; i < n; ++i)
    s.add(-hw + s.uniform(-h, h), s.uniform(top, bottom), s.uniform(-hd, hd),
          PointLabel::kOtherWall);
  surf.push_back({Eigen::Vector3d::UnitX(), -hw});
  for (std::size_t i = 0; i < n; ++i)
    s.add(s.uniform(-hw, hw), bottom + s.uniform(-h, h), s.uniform(-hd, hd), PointLabel::kFloor);
  surf.push_back({-Eigen::Vector3d::UnitY(), -bottom});  // floor: front is up (-y)
  for (std::size_t i = 0; i < n; ++i)
    s.add(s.uniform(-hw, hw), top + s.uniform(-h, h), s.uniform(-hd, hd), PointLabel::kCeiling);
  surf.push_back({Eigen::Vector3d::UnitY(), top});  // ceiling: front is down (+y)
  for (std::size_t i = 0; i < p.clutter; ++i) {
    s.add(s.uniform(-hw + 0.3, hw - 0.3), s.uniform(top + 0.3, bottom - 0.3),
          s.uniform(-hd + 0.3, hd - 0.3), PointLabel::kOutlier);
  }
  s.out.wall = surf.front();
  return std::move(s.out);
}

}  // namespace wallar::dsp
