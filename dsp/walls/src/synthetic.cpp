// SPDX-License-Identifier: Apache-2.0
/// @file synthetic.cpp
/// @brief Labelled synthetic scenes for tests, evaluation and benchmarks.
#include "wallar/dsp/walls/synthetic.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

namespace wallar::dsp {
namespace {

class Scene {
 public:
  explicit Scene(std::uint64_t seed) : rng_(seed) {}
  // Not std::uniform_real_distribution: its result is implementation-defined (libstdc++ gives
  // different scenes on x86-64 and aarch64 for the same seed). 53 random bits -> [0, 1).
  double uniform(double lo, double hi) {
    const double u = static_cast<double>(rng_() >> 11) * 0x1.0p-53;
    return lo + (hi - lo) * u;
  }
  // Callers draw z, then y, then x into locals before calling: function arguments are
  // evaluated in an unspecified order (GCC on x86-64 went right to left, on aarch64 not), so
  // drawing inside the argument list gave each platform a different scene for one seed.
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
    const double z = p.wall_distance_m + s.uniform(-half, half);  // z, y, x: see add()
    const double y = s.uniform(-w, w);
    const double x = s.uniform(-w, w);
    s.add(x, y, z, PointLabel::kWall);
  }
  const double q = p.plane_size_m / 2;
  for (std::size_t i = 0; i < p.plane_points; ++i) {
    const double z = p.plane_distance_m + s.uniform(-half, half);  // z, y, x: see add()
    const double y = s.uniform(-q, q);
    const double x = s.uniform(-q, q);
    s.add(x, y, z, PointLabel::kFrontPlane);
  }
  const double rho = std::clamp(p.rho_b, 0.0, 0.95);
  const auto backliers =
      static_cast<std::size_t>(std::lround(rho / (1.0 - rho) * static_cast<double>(p.wall_points)));
  for (std::size_t i = 0; i < backliers; ++i) {
    const double z =
        p.wall_distance_m + half + s.uniform(0.0, p.backlier_depth_m);  // z, y, x: see add()
    const double y = s.uniform(-w, w);
    const double x = s.uniform(-w, w);
    s.add(x, y, z, PointLabel::kBacklier);
  }
  for (std::size_t i = 0; i < p.outliers; ++i) {
    const double z = s.uniform(0.1, p.wall_distance_m - half);  // z, y, x: see add()
    const double y = s.uniform(-w, w);
    const double x = s.uniform(-w, w);
    s.add(x, y, z, PointLabel::kOutlier);
  }
  // A window: points outside, seen through the opening, so they lie in its viewing cone.
  const double ww = p.window_size_m / 2;
  for (std::size_t i = 0; i < p.window_points; ++i) {
    const double z = p.wall_distance_m + 0.5 +
                     s.uniform(0.0, std::max(0.0, p.window_depth_m - 0.5));  // z, v, u: see add()
    const double v = s.uniform(-ww, ww);
    const double u = p.window_x_m + s.uniform(-ww, ww);
    const double scale = z / p.wall_distance_m;  // through (u, v) on the wall, from the origin
    s.add(u * scale, v * scale, z, PointLabel::kWindow);
  }
  // Boxes: a size, a footprint between the front plane and the wall, and points on the three
  // faces a viewer at the origin sees (front z-, top y-, the side facing the origin in x).
  if (p.clutter_points > 0) {
    const std::size_t objects = std::max<std::size_t>(1, p.clutter_objects);
    for (std::size_t k = 0; k < objects; ++k) {
      const double size = s.uniform(0.3, 0.8);
      const double z0 = s.uniform(p.plane_distance_m + 0.2, p.wall_distance_m - size - 0.1);
      const double x0 = s.uniform(-w, w - size);
      const double y_floor = w;  // boxes stand on the wall's bottom edge line (y down)
      const std::size_t n = p.clutter_points / objects + (k < p.clutter_points % objects ? 1 : 0);
      for (std::size_t i = 0; i < n; ++i) {
        const double face = s.uniform(0.0, 3.0);  // then a, b: see add()
        const double a = s.uniform(0.0, size);
        const double b = s.uniform(0.0, size);
        const double jitter = s.uniform(-half, half);
        if (face < 1.0) {  // front face, z = z0
          s.add(x0 + a, y_floor - b, z0 + jitter, PointLabel::kClutter);
        } else if (face < 2.0) {  // top face, y = y_floor - size
          s.add(x0 + a, y_floor - size + jitter, z0 + b, PointLabel::kClutter);
        } else {  // the side nearer x = 0
          const double side_x = x0 + size / 2 > 0 ? x0 : x0 + size;
          s.add(side_x + jitter, y_floor - a, z0 + b, PointLabel::kClutter);
        }
      }
    }
  }
  s.out.wall = Plane{-Eigen::Vector3d::UnitZ(), -p.wall_distance_m};
  return std::move(s.out);
}

const char* label_name(PointLabel label) {
  switch (label) {
    case PointLabel::kWall:
      return "wall";
    case PointLabel::kFrontPlane:
      return "front_plane";
    case PointLabel::kBacklier:
      return "backlier";
    case PointLabel::kOutlier:
      return "outlier";
    case PointLabel::kFloor:
      return "floor";
    case PointLabel::kCeiling:
      return "ceiling";
    case PointLabel::kOtherWall:
      return "other_wall";
    case PointLabel::kWindow:
      return "window";
    case PointLabel::kClutter:
      return "clutter";
  }
  return "unknown";
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
    const double z = p.wall_distance_m + s.uniform(-half, half);  // z, y, x: see add()
    const double y = s.uniform(-1.5, 1.5);
    const double x = s.uniform(-2.0, 2.0);
    s.add(x, y, z, PointLabel::kWall);
  }
  for (std::size_t i = 0; i < back && wall + i < p.points; ++i) {
    const double z = p.wall_distance_m + half + s.uniform(0.0, 1.0);  // z, y, x: see add()
    const double y = s.uniform(-1.5, 1.5);
    const double x = s.uniform(-2.0, 2.0);
    s.add(x, y, z, PointLabel::kBacklier);
  }
  const double cabinet_z = p.wall_distance_m - 0.6;
  for (std::size_t i = 0; i < p.front_plane_points && s.out.cloud.size() < p.points; ++i) {
    const double z = cabinet_z + s.uniform(-half, half);  // z, y, x: see add()
    const double y = s.uniform(0.5, 1.5);
    const double x = s.uniform(-0.5, 0.5);
    s.add(x, y, z, PointLabel::kFrontPlane);
  }
  const auto side = static_cast<std::size_t>(
      std::lround(std::clamp(p.side_wall_fraction, 0.0, 0.5) * static_cast<double>(p.points)));
  for (std::size_t i = 0; i < side && s.out.cloud.size() < p.points; ++i) {
    const double z = s.uniform(0.5, p.wall_distance_m);  // z, y, x: see add()
    const double y = s.uniform(-1.5, 1.5);
    const double x = 2.0 + s.uniform(-half, half);
    s.add(x, y, z, PointLabel::kOtherWall);
  }
  std::vector<Eigen::Vector3d> centres;
  for (std::size_t k = 0; k < p.clutter_clusters; ++k) {
    const double z = s.uniform(0.8, p.wall_distance_m - 0.3);  // z, y, x: see add()
    const double y = s.uniform(-1.5, 1.5);
    const double x = s.uniform(-2.0, 2.0);
    centres.emplace_back(x, y, z);
  }
  // A standard normal from two uniforms (Box-Muller): portable, unlike <random>'s.
  const auto normal = [&s] {
    const double u1 = 1.0 - s.uniform(0.0, 1.0);  // (0, 1]
    const double u2 = s.uniform(0.0, 1.0);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  };
  while (s.out.cloud.size() < p.points) {
    if (centres.empty()) {
      const double z = s.uniform(0.5, p.wall_distance_m - half);  // z, y, x: see add()
      const double y = s.uniform(-1.5, 1.5);
      const double x = s.uniform(-2.0, 2.0);
      s.add(x, y, z, PointLabel::kOutlier);
      continue;
    }
    const auto k = static_cast<std::size_t>(s.uniform(0.0, static_cast<double>(centres.size())));
    const Eigen::Vector3d& c = centres[std::min(k, centres.size() - 1)];
    const double dz = 0.15 * normal();  // z, y, x: see add()
    const double dy = 0.15 * normal();
    const double dx = 0.15 * normal();
    // Clumps stay in front of the wall's band.
    const double z = std::min(c.z() + dz, p.wall_distance_m - half);
    s.add(c.x() + dx, c.y() + dy, z, PointLabel::kClutter);
  }
  s.out.wall = Plane{-Eigen::Vector3d::UnitZ(), -p.wall_distance_m};
  s.out.surfaces.push_back(s.out.wall);
  s.out.all_walls.push_back(s.out.wall);
  if (p.front_plane_points > 0) s.out.surfaces.push_back({-Eigen::Vector3d::UnitZ(), -cabinet_z});
  if (side > 0) {
    s.out.surfaces.push_back({-Eigen::Vector3d::UnitX(), -2.0});
    s.out.all_walls.push_back(s.out.surfaces.back());
  }
  if (p.tilt_deg != 0.0 || p.yaw_deg != 0.0) {
    // About the origin (the viewpoint): the planes' d stays.
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(p.tilt_deg * M_PI / 180.0, Eigen::Vector3d::UnitX()) *
         Eigen::AngleAxisd(p.yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()))
            .toRotationMatrix();
    PointCloud& c = s.out.cloud;
    for (std::size_t i = 0; i < c.size(); ++i) {
      const Eigen::Vector3d q = R * Eigen::Vector3d(c.x[i], c.y[i], c.z[i]);
      c.x[i] = static_cast<float>(q.x());
      c.y[i] = static_cast<float>(q.y());
      c.z[i] = static_cast<float>(q.z());
    }
    s.out.wall.n = R * s.out.wall.n;
    for (Plane& plane : s.out.surfaces) plane.n = R * plane.n;
    for (Plane& plane : s.out.all_walls) plane.n = R * plane.n;
    s.out.down = R * s.out.down;
  }
  return std::move(s.out);
}

SparseMapParams sparse_map_family(std::uint64_t seed) {
  Scene s(seed ^ 0x5eed'fa41'17u);
  SparseMapParams p;
  p.seed = seed;
  p.wall_fraction = s.uniform(0.02, 0.10);
  p.tilt_deg = s.uniform(0.0, 20.0);
  p.front_plane_points = s.uniform(0.0, 1.0) < 0.5 ? 60 : 0;
  p.clutter_clusters =
      s.uniform(0.0, 1.0) < 0.5 ? 0 : static_cast<std::size_t>(s.uniform(4.0, 13.0));
  p.wall_distance_m = s.uniform(2.5, 4.5);
  const bool corner = s.uniform(0.0, 1.0) < 0.5;
  p.side_wall_fraction = corner ? s.uniform(0.02, 0.10) : 0.0;
  p.yaw_deg = corner ? -s.uniform(15.0, 35.0) : s.uniform(-20.0, 20.0);
  return p;
}

LabelledCloud make_room_scene(const RoomSceneParams& p) {
  Scene s(p.seed);
  const double hw = p.width_m / 2, hd = p.depth_m / 2, h = p.noise_m / 2;
  const double top = -p.ceiling_above_m, bottom = p.floor_below_m;  // y is down
  const std::size_t n = p.points_per_surface;
  auto& surf = s.out.surfaces;
  // Walls first (front z+, then right x+, back z-, left x-), then floor and ceiling; each
  // normal points into the room, toward the viewpoint at the origin.
  for (std::size_t i = 0; i < n; ++i) {
    const double z = hd + s.uniform(-h, h);  // z, y, x: see add()
    const double y = s.uniform(top, bottom);
    const double x = s.uniform(-hw, hw);
    s.add(x, y, z, PointLabel::kWall);
  }
  surf.push_back({-Eigen::Vector3d::UnitZ(), -hd});
  for (std::size_t i = 0; i < n; ++i) {
    const double z = s.uniform(-hd, hd);  // z, y, x: see add()
    const double y = s.uniform(top, bottom);
    const double x = hw + s.uniform(-h, h);
    s.add(x, y, z, PointLabel::kOtherWall);
  }
  surf.push_back({-Eigen::Vector3d::UnitX(), -hw});
  for (std::size_t i = 0; i < n; ++i) {
    const double z = -hd + s.uniform(-h, h);  // z, y, x: see add()
    const double y = s.uniform(top, bottom);
    const double x = s.uniform(-hw, hw);
    s.add(x, y, z, PointLabel::kOtherWall);
  }
  surf.push_back({Eigen::Vector3d::UnitZ(), -hd});
  for (std::size_t i = 0; i < n; ++i) {
    const double z = s.uniform(-hd, hd);  // z, y, x: see add()
    const double y = s.uniform(top, bottom);
    const double x = -hw + s.uniform(-h, h);
    s.add(x, y, z, PointLabel::kOtherWall);
  }
  surf.push_back({Eigen::Vector3d::UnitX(), -hw});
  for (std::size_t i = 0; i < n; ++i) {
    const double z = s.uniform(-hd, hd);  // z, y, x: see add()
    const double y = bottom + s.uniform(-h, h);
    const double x = s.uniform(-hw, hw);
    s.add(x, y, z, PointLabel::kFloor);
  }
  surf.push_back({-Eigen::Vector3d::UnitY(), -bottom});  // floor: front is up (-y)
  for (std::size_t i = 0; i < n; ++i) {
    const double z = s.uniform(-hd, hd);  // z, y, x: see add()
    const double y = top + s.uniform(-h, h);
    const double x = s.uniform(-hw, hw);
    s.add(x, y, z, PointLabel::kCeiling);
  }
  surf.push_back({Eigen::Vector3d::UnitY(), top});  // ceiling: front is down (+y)
  for (std::size_t i = 0; i < p.clutter; ++i) {
    const double z = s.uniform(-hd + 0.3, hd - 0.3);  // z, y, x: see add()
    const double y = s.uniform(top + 0.3, bottom - 0.3);
    const double x = s.uniform(-hw + 0.3, hw - 0.3);
    s.add(x, y, z, PointLabel::kOutlier);
  }
  s.out.wall = surf.front();
  return std::move(s.out);
}

}  // namespace wallar::dsp
