// SPDX-License-Identifier: Apache-2.0
/// @file test_synthetic_room.cpp
/// @brief The synthetic stereo room: hit geometry, stereo consistency, determinism, the
/// trajectory's clearance and the texture's corners.
///
/// Set WALLAR_DUMP_SYNTHETIC_ROOM=DIR to write the rendered pair as DIR/room_{left,right}.pgm.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "wallar/dsp/tracking/synthetic_room.hpp"

namespace wallar::dsp {
namespace {

using Pixels = std::vector<std::uint8_t>;

Pixels render(const SyntheticRoom& room, const SyntheticCamera& camera, const SE3d& T_world_cam,
             int cam) {
  Pixels img(static_cast<std::size_t>(camera.width_px * camera.height_px));
  render_room(room, camera, T_world_cam, cam, img);
  return img;
}

void maybe_dump(const Pixels& img, const SyntheticCamera& camera, const std::string& name) {
  const char* dir = std::getenv("WALLAR_DUMP_SYNTHETIC_ROOM");
  if (dir == nullptr) return;
  std::ofstream f(std::string(dir) + "/" + name + ".pgm", std::ios::binary);
  f << "P5\n" << camera.width_px << " " << camera.height_px << "\n255\n";
  f.write(reinterpret_cast<const char*>(img.data()), static_cast<std::streamsize>(img.size()));
}

// A pose from the trajectory a few seconds in (heading off-axis, pitched, rolled).
SE3d test_pose(const SyntheticRoom& room) {
  return synthetic_trajectory(room, 61, 20.0)[60].T_world_body;
}

// The camera-frame ray of pixel (u, v).
Eigen::Vector3d pixel_ray(const SyntheticCamera& c, double u, double v) {
  return {(u - c.cx_px) / c.f_px, (v - c.cy_px) / c.f_px, 1.0};
}

TEST(SyntheticRoom, PlanesPointIntoTheRoom) {
  const SyntheticRoom room;
  const Eigen::Vector3d centre(0.5, -1.0, 1.2);
  for (const Eigen::Vector4d& pl : room.planes()) {
    EXPECT_NEAR(pl.head<3>().norm(), 1.0, 1e-12);
    EXPECT_GT(pl.head<3>().dot(centre) - pl[3], 0.0);  // the inside is on the normal's side
  }
  EXPECT_NEAR(room.distance_to_nearest_surface(centre), 1.2, 1e-12);  // floor
  EXPECT_NEAR(room.distance_to_nearest_surface({2.9, 0, 1.5}), 0.1, 1e-12);
}

TEST(SyntheticRoom, RayHitsLieOnTheExpectedPlane) {
  const SyntheticRoom room;
  const SyntheticCamera camera;
  const SE3d T = test_pose(room);
  const auto planes = room.planes();
  int surfaces_seen = 0;
  std::array<bool, 6> seen{};
  for (const auto& [u, v] : std::vector<std::pair<double, double>>{
           {0, 0}, {751, 0}, {0, 479}, {751, 479}, {375.5, 239.5}, {100, 400}, {600, 50}}) {
    const Eigen::Vector3d d = T.linear() * pixel_ray(camera, u, v);
    const auto hit = ray_hit(room, T.translation(), d);
    ASSERT_TRUE(hit.has_value());
    const Eigen::Vector4d& pl = planes[static_cast<std::size_t>(hit->surface)];
    EXPECT_NEAR(pl.head<3>().dot(hit->p_world) - pl[3], 0.0, 1e-9);
    EXPECT_LT(room.distance_to_nearest_surface(hit->p_world), 1e-9);
    EXPECT_GT(hit->range, 0.0);
    // The hit is in front of the camera along the pixel's ray.
    const Eigen::Vector3d p_cam = T.inverse() * hit->p_world;
    EXPECT_NEAR(p_cam.x() / p_cam.z(), (u - camera.cx_px) / camera.f_px, 1e-9);
    EXPECT_NEAR(p_cam.y() / p_cam.z(), (v - camera.cy_px) / camera.f_px, 1e-9);
    if (!seen[static_cast<std::size_t>(hit->surface)]) ++surfaces_seen;
    seen[static_cast<std::size_t>(hit->surface)] = true;
  }
  EXPECT_GE(surfaces_seen, 2);

  // Hand-checked: from (0, 0, 1.5) straight along +y hits the y_max wall at (0, 4, 1.5).
  const auto hit = ray_hit(room, {0, 0, 1.5}, {0, 2, 0});
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->surface, RoomFace::kYMax);
  EXPECT_TRUE(hit->p_world.isApprox(Eigen::Vector3d(0, 4, 1.5)));
  EXPECT_DOUBLE_EQ(hit->range, 2.0);
  const auto down = ray_hit(room, {1, 1, 1.5}, {0.1, 0, -1});
  ASSERT_TRUE(down.has_value());
  EXPECT_EQ(down->surface, RoomFace::kFloor);
  EXPECT_FALSE(ray_hit(room, {0, 0, 3.5}, {0, 0, -1}).has_value());  // outside
  EXPECT_FALSE(ray_hit(room, {0, 0, 1}, {0, 0, 0}).has_value());
}

// Sum of squared differences of a (2r+1)^2 block at left (ul, v) and right (ul - disparity, v),
// the right image linearly interpolated along the row.
double ssd(const Pixels& l, const Pixels& r, int w, int ul, int v, double disparity, int radius) {
  double s = 0;
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      const double ur = ul + dx - disparity;
      const int i = static_cast<int>(std::floor(ur));
      const double f = ur - i;
      const std::size_t row = static_cast<std::size_t>((v + dy) * w);
      const double right = (1 - f) * r[row + static_cast<std::size_t>(i)] +
                           f * r[row + static_cast<std::size_t>(i + 1)];
      const double diff = l[row + static_cast<std::size_t>(ul + dx)] - right;
      s += diff * diff;
    }
  }
  return s;
}

// The true disparity of left pixel (u, v) and the surface it sees.
std::pair<double, RoomFace> true_disparity(const SyntheticRoom& room, const SyntheticCamera& c,
                                              const SE3d& T, int u, int v) {
  const auto hit = ray_hit(room, T.translation(), T.linear() * pixel_ray(c, u, v));
  if (!hit) return {0.0, RoomFace::kFloor};
  return {c.f_px * c.baseline_m / (T.inverse() * hit->p_world).z(), hit->surface};
}

TEST(SyntheticRoom, DisparityMatchesDepth) {
  const SyntheticRoom room;
  const SyntheticCamera camera;
  const SE3d T = test_pose(room);
  const Pixels left = render(room, camera, T, 0);
  const Pixels right = render(room, camera, T, 1);
  maybe_dump(left, camera, "room_left");
  maybe_dump(right, camera, "room_right");
  const int w = camera.width_px;
  constexpr int kRadius = 6;
  int checked = 0;
  double worst = 0;
  for (int v = 60; v < camera.height_px - 60; v += 45) {
    for (int u = 120; u < w - 40; u += 53) {
      // On a slanted wall the disparity changes across the block, and a block match measures
      // the disparity where the texture is (weights: squared horizontal gradient), so that
      // weighted mean is the expectation. Blocks across a room edge are skipped.
      double weight_sum = 0, expected = 0;
      bool one_surface = true;
      const RoomFace centre_surface = true_disparity(room, camera, T, u, v).second;
      for (int dy = -kRadius; dy <= kRadius; ++dy) {
        for (int dx = -kRadius; dx <= kRadius; ++dx) {
          const auto [disp, surface] = true_disparity(room, camera, T, u + dx, v + dy);
          one_surface = one_surface && surface == centre_surface;
          const std::size_t i = static_cast<std::size_t>((v + dy) * w + u + dx);
          const double gx = 0.5 * (left[i + 1] - left[i - 1]);
          weight_sum += gx * gx;
          expected += gx * gx * disp;
        }
      }
      if (!one_surface || weight_sum < 169 * 100.0) continue;  // untextured: RMS gradient < 10
      expected /= weight_sum;
      // Integer search along the same row (rectified: no vertical offset), then 0.01 px steps.
      double best_cost = std::numeric_limits<double>::infinity();
      int best = 0;
      for (int disp = 0; disp <= std::min(80, u - kRadius - 2); ++disp) {
        const double c = ssd(left, right, w, u, v, disp, kRadius);
        if (c < best_cost) {
          best_cost = c;
          best = disp;
        }
      }
      double measured = best;
      for (double disp = best - 1.0; disp <= best + 1.0; disp += 0.01) {
        const double c = ssd(left, right, w, u, v, disp, kRadius);
        if (c < best_cost) {
          best_cost = c;
          measured = disp;
        }
      }
      EXPECT_NEAR(measured, expected, 0.3) << "at (" << u << ", " << v << ")";
      worst = std::max(worst, std::abs(measured - expected));
      ++checked;
    }
  }
  EXPECT_GE(checked, 30);
  RecordProperty("worst_disparity_error_px", std::to_string(worst));
  std::printf("disparity: %d blocks, worst error %.3f px\n", checked, worst);
}

TEST(SyntheticRoom, SameSeedSameBytesOtherSeedOtherImage) {
  SyntheticRoom room;
  const SyntheticCamera camera;
  const SE3d T = test_pose(room);
  const Pixels a = render(room, camera, T, 0);
  const Pixels b = render(room, camera, T, 0);
  EXPECT_EQ(a, b);
  room.texture_seed = 2;
  const Pixels c = render(room, camera, T, 0);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) differ += a[i] != c[i] ? 1 : 0;
  EXPECT_GT(differ, a.size() / 2);
  EXPECT_EQ(synthetic_trajectory(room, 50, 20.0, 7)[49].T_world_body.matrix(),
            synthetic_trajectory(room, 50, 20.0, 7)[49].T_world_body.matrix());
}

TEST(SyntheticRoom, TrajectoryIsSmoothClosedAndClearOfTheWalls) {
  const SyntheticRoom room;
  constexpr double kRate = 20.0;
  const int n = static_cast<int>(kSyntheticTrajectoryPeriodS * kRate) + 1;
  const auto traj = synthetic_trajectory(room, n, kRate, 1'000'000'000);
  ASSERT_EQ(traj.size(), static_cast<std::size_t>(n));
  EXPECT_EQ(traj.front().t_ns, 1'000'000'000);
  EXPECT_EQ(traj[1].t_ns - traj[0].t_ns, 50'000'000);
  double path = 0;
  for (std::size_t k = 0; k < traj.size(); ++k) {
    const SE3d& T = traj[k].T_world_body;
    EXPECT_GE(room.distance_to_nearest_surface(T.translation()), 0.5);
    EXPECT_NEAR((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).norm(), 0,
                1e-12);
    EXPECT_GT(T.linear().determinant(), 0.0);
    // Roughly horizontal: the optical axis within 15 deg of level.
    EXPECT_LT(std::abs(T.linear().col(2).z()), std::sin(15.0 * M_PI / 180.0));
    if (k > 0) {
      const SE3d step = traj[k - 1].T_world_body.inverse() * T;
      EXPECT_LT(step.translation().norm(), 0.05);  // smooth: < 1 m/s
      EXPECT_LT(Eigen::AngleAxisd(step.linear()).angle(), 2.0 * M_PI / 180.0);
      path += step.translation().norm();
    }
  }
  // Closed: one period later the pose repeats.
  EXPECT_TRUE(traj.back().T_world_body.isApprox(traj.front().T_world_body, 1e-9));
  EXPECT_GT(path, 3.0);
  std::printf("trajectory: %.2f m per %.0f s period\n", path, kSyntheticTrajectoryPeriodS);
}

// FAST-9 segment test: 9 contiguous of the 16 circle pixels all brighter than p + t or all
// darker than p - t.
bool fast9(const Pixels& img, int w, int u, int v, int threshold) {
  static constexpr std::array<std::array<int, 2>, 16> kCircle = {{{0, -3},
                                                                  {1, -3},
                                                                  {2, -2},
                                                                  {3, -1},
                                                                  {3, 0},
                                                                  {3, 1},
                                                                  {2, 2},
                                                                  {1, 3},
                                                                  {0, 3},
                                                                  {-1, 3},
                                                                  {-2, 2},
                                                                  {-3, 1},
                                                                  {-3, 0},
                                                                  {-3, -1},
                                                                  {-2, -2},
                                                                  {-1, -3}}};
  const int p = img[static_cast<std::size_t>(v * w + u)];
  std::array<int, 16> state{};  // +1 brighter, -1 darker, 0 similar
  for (std::size_t k = 0; k < 16; ++k) {
    const int q = img[static_cast<std::size_t>((v + kCircle[k][1]) * w + u + kCircle[k][0])];
    state[k] = q > p + threshold ? 1 : (q < p - threshold ? -1 : 0);
  }
  for (const int sign : {1, -1}) {
    int run = 0;
    for (int k = 0; k < 32; ++k) {
      run = state[static_cast<std::size_t>(k % 16)] == sign ? run + 1 : 0;
      if (run >= 9) return true;
    }
  }
  return false;
}

TEST(SyntheticRoom, ManyWellSpreadCorners) {
  const SyntheticRoom room;
  const SyntheticCamera camera;
  const auto traj = synthetic_trajectory(room, 400, 20.0);
  // Under an emulator (WALLAR_SHORT_TESTS, qemu renders ~20x slower) two of the five poses.
  const std::vector<std::size_t> poses = std::getenv("WALLAR_SHORT_TESTS") != nullptr
                                             ? std::vector<std::size_t>{0, 250}
                                             : std::vector<std::size_t>{0, 60, 130, 250, 330};
  for (const std::size_t k : poses) {
    const Pixels img = render(room, camera, traj[k].T_world_body, 0);
    const int w = camera.width_px, h = camera.height_px;
    int total = 0;
    std::array<int, 16> cells{};
    for (int v = 3; v < h - 3; ++v) {
      for (int u = 3; u < w - 3; ++u) {
        if (!fast9(img, w, u, v, 20)) continue;
        ++total;
        ++cells[static_cast<std::size_t>((v * 4 / h) * 4 + u * 4 / w)];
      }
    }
    const auto occupied = std::count_if(cells.begin(), cells.end(), [](int c) { return c >= 5; });
    EXPECT_GE(total, 300) << "pose " << k;
    EXPECT_GE(occupied, 12) << "pose " << k;
    std::printf("pose %zu: %d FAST-9 pixels, %ld of 16 cells with >= 5\n", k, total,
                static_cast<long>(occupied));
  }
}

TEST(SyntheticRoom, RejectsBadArguments) {
  const SyntheticRoom room;
  const SyntheticCamera camera;
  Pixels img(10);
  EXPECT_THROW(render_room(room, camera, SE3d::Identity(), 0, img), std::invalid_argument);
  Pixels full(static_cast<std::size_t>(camera.width_px * camera.height_px));
  EXPECT_THROW(render_room(room, camera, SE3d::Identity(), 2, full), std::invalid_argument);
  EXPECT_THROW((void)synthetic_trajectory(room, -1, 20.0), std::invalid_argument);
  EXPECT_THROW((void)synthetic_trajectory(room, 10, 0.0), std::invalid_argument);
  // A camera outside the room sees nothing.
  SE3d outside = SE3d::Identity();
  outside.translation() = Eigen::Vector3d(0, 0, -1);
  render_room(room, camera, outside, 0, full);
  EXPECT_TRUE(std::all_of(full.begin(), full.end(), [](std::uint8_t b) { return b == 0; }));
}

}  // namespace
}  // namespace wallar::dsp
