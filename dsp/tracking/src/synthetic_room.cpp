// SPDX-License-Identifier: Apache-2.0
/// @file synthetic_room.cpp
/// @brief Ray casting into a textured box room, and the trajectory that tours it.
#include "wallar/dsp/tracking/synthetic_room.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "wallar/core/hash.hpp"

namespace wallar::dsp {
namespace {

using core::mix64;

std::uint64_t cell_hash(std::uint64_t key, std::int64_t i, std::int64_t j) {
  return mix64(key ^ mix64(static_cast<std::uint64_t>(i) * 0xD1B54A32D192ED03ULL +
                           static_cast<std::uint64_t>(j) * 0xABC98388FB8FAC03ULL));
}

// 53 bits of h -> [0, 1).
double unit(std::uint64_t h) { return static_cast<double>(h >> 11) * 0x1.0p-53; }

// floor() for the texture's cell indices (|x| is far below 2^62); std::floor compiles to one
// rounding instruction on both targets (SSE4.1 roundsd, A64 frintm), cheaper than a compare.
std::int64_t floor_i(double x) { return static_cast<std::int64_t>(std::floor(x)); }

// Shape layers, painted from the largest cells to the smallest: each cell of a layer holds at
// most one rectangle or disc inside the cell, so a point needs one lookup per layer.
constexpr std::size_t kLayers = 3;
constexpr std::array<double, kLayers> kCellM = {0.5, 0.25, 0.13};
// 1 / kCellM, folded at compile time (the same doubles a run-time division gives): the texture
// is sampled several times per pixel and a division per sample and layer showed in profiles.
constexpr std::array<double, kLayers> kInvCellM = {1.0 / kCellM[0], 1.0 / kCellM[1],
                                                   1.0 / kCellM[2]};
constexpr std::array<double, kLayers> kShapeProbability = {0.6, 0.5, 0.4};

std::uint64_t surface_key(std::uint64_t seed, int surface) {
  return mix64(mix64(seed) ^ (0x5851F42D4C957F2DULL * static_cast<std::uint64_t>(surface + 1)));
}

double base_gray(std::uint64_t key) { return 105.0 + 40.0 * unit(mix64(key ^ 0x1234ULL)); }

// One cell's shape, in cell units ([0, 1) across the cell).
struct Shape {
  bool present = false;
  bool rectangle = false;
  double gray = 0;
  double a = 0, b = 0, c = 0,
         d = 0;  // rectangle [a, a + c) x [b, b + d); disc centre (a, b), r^2 c

  [[nodiscard]] bool contains(double fs, double ft) const {
    if (rectangle) return fs >= a && fs < a + c && ft >= b && ft < b + d;
    return (fs - a) * (fs - a) + (ft - b) * (ft - b) < c;
  }
};

Shape make_shape(std::uint64_t key, std::size_t layer, std::int64_t i, std::int64_t j) {
  Shape shape;
  std::uint64_t h = cell_hash(key + 0x100ULL * (layer + 1), i, j);
  if (unit(h) >= kShapeProbability[layer]) return shape;
  shape.present = true;
  auto next = [&h] {
    h = mix64(h);
    return unit(h);
  };
  shape.rectangle = next() < 0.7;
  // Dark or light, never mid-gray: every shape contrasts with the ~105-145 background.
  const double tone = next();
  shape.gray = tone < 0.5 ? 15.0 + 160.0 * tone : 160.0 + 160.0 * (tone - 0.5);
  if (shape.rectangle) {
    shape.c = 0.35 + 0.5 * next();  // width
    shape.d = 0.35 + 0.5 * next();  // height
    shape.a = (1.0 - shape.c) * next();
    shape.b = (1.0 - shape.d) * next();
  } else {
    const double r = 0.18 + 0.27 * next();
    shape.a = r + (1.0 - 2.0 * r) * next();
    shape.b = r + (1.0 - 2.0 * r) * next();
    shape.c = r * r;
  }
  return shape;
}

// Value noise lattice values in [-1, 1].
double lattice(std::uint64_t key, std::int64_t i, std::int64_t j) {
  return 2.0 * unit(cell_hash(key, i, j)) - 1.0;
}

constexpr std::array<double, 2> kNoiseCellM = {0.1, 0.035};
constexpr std::array<double, 2> kInvNoiseCellM = {1.0 / kNoiseCellM[0], 1.0 / kNoiseCellM[1]};
constexpr std::array<double, 2> kNoiseAmplitude = {16.0, 7.0};
constexpr std::array<std::uint64_t, 2> kNoiseSalt = {0xA1ULL, 0xB2ULL};

// Evaluates the texture with the cells last used remembered: neighbouring samples nearly always
// fall into the same cells, so most samples need no hashing at all.
class TextureSampler {
 public:
  explicit TextureSampler(std::uint64_t seed) {
    for (int k = 0; k < 6; ++k) {
      const std::uint64_t key = surface_key(seed, k);
      keys_[static_cast<std::size_t>(k)] = key;
      base_[static_cast<std::size_t>(k)] = base_gray(key);
    }
  }

  // The shapes alone (no noise): what render_room supersamples.
  double shapes(int surface, double s, double t) {
    const auto k = static_cast<std::size_t>(surface);
    // Smaller shapes are painted over larger ones: the first (smallest) layer whose shape
    // contains the point decides.
    for (std::size_t layer = kLayers; layer-- > 0;) {
      const double gs = s * kInvCellM[layer], gt = t * kInvCellM[layer];
      const std::int64_t i = floor_i(gs), j = floor_i(gt);
      ShapeEntry& e = shape_cache_[layer];
      if (e.surface != surface || e.i != i || e.j != j) {
        e = {surface, i, j, make_shape(keys_[k], layer, i, j)};
      }
      if (e.shape.present &&
          e.shape.contains(gs - static_cast<double>(i), gt - static_cast<double>(j))) {
        return e.shape.gray;
      }
    }
    return base_[k];
  }

  // Low-contrast value noise everywhere, so block matching also works inside large shapes.
  double noise(int surface, double s, double t) {
    const auto k = static_cast<std::size_t>(surface);
    double value = 0.0;
    for (std::size_t o = 0; o < kNoiseCellM.size(); ++o) {
      const double x = s * kInvNoiseCellM[o], y = t * kInvNoiseCellM[o];
      const std::int64_t i = floor_i(x), j = floor_i(y);
      NoiseEntry& e = noise_cache_[o];
      if (e.surface != surface || e.i != i || e.j != j) {
        const std::uint64_t key = keys_[k] ^ kNoiseSalt[o];
        e = {surface,
             i,
             j,
             {lattice(key, i, j), lattice(key, i + 1, j), lattice(key, i, j + 1),
              lattice(key, i + 1, j + 1)}};
      }
      const double fx = x - static_cast<double>(i), fy = y - static_cast<double>(j);
      const double sx = fx * fx * (3.0 - 2.0 * fx), sy = fy * fy * (3.0 - 2.0 * fy);
      const auto& v = e.v;
      value += kNoiseAmplitude[o] *
               ((v[0] + (v[1] - v[0]) * sx) * (1.0 - sy) + (v[2] + (v[3] - v[2]) * sx) * sy);
    }
    return value;
  }

 private:
  struct ShapeEntry {
    int surface = -1;
    std::int64_t i = 0, j = 0;
    Shape shape;
  };
  struct NoiseEntry {
    int surface = -1;
    std::int64_t i = 0, j = 0;
    std::array<double, 4> v{};
  };
  std::array<std::uint64_t, 6> keys_{};
  std::array<double, 6> base_{};
  std::array<ShapeEntry, kLayers> shape_cache_{};
  std::array<NoiseEntry, 2> noise_cache_{};
};

// (s, t) surface coordinates of a point on `surface`.
void surface_coords(RoomFace surface, const Eigen::Vector3d& p, double& s, double& t) {
  switch (surface) {
    case RoomFace::kXMin:
    case RoomFace::kXMax:
      s = p.y();
      t = p.z();
      return;
    case RoomFace::kYMin:
    case RoomFace::kYMax:
      s = p.x();
      t = p.z();
      return;
    case RoomFace::kFloor:
    case RoomFace::kCeiling:
      s = p.x();
      t = p.y();
      return;
  }
}

struct Box {
  Eigen::Vector3d lo, hi;
};

Box box_of(const SyntheticRoom& room) {
  return {Eigen::Vector3d(room.x_min_m, room.y_min_m, 0.0),
          Eigen::Vector3d(room.x_max_m, room.y_max_m, room.z_max_m)};
}

// The exit point of a ray from inside the box: nearest of the three faces it heads toward.
bool cast(const Box& box, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& range,
          RoomFace& surface) {
  range = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 0.0) {
      const double r = (box.hi[a] - o[a]) / d[a];
      if (r < range) {
        range = r;
        surface = static_cast<RoomFace>(a == 2 ? 5 : 2 * a + 1);
      }
    } else if (d[a] < 0.0) {
      const double r = (box.lo[a] - o[a]) / d[a];
      if (r < range) {
        range = r;
        surface = static_cast<RoomFace>(a == 2 ? 4 : 2 * a);
      }
    }
  }
  return std::isfinite(range);
}

bool inside(const Box& box, const Eigen::Vector3d& p) {
  return (p.array() > box.lo.array()).all() && (p.array() < box.hi.array()).all();
}

}  // namespace

std::array<Eigen::Vector4d, 6> SyntheticRoom::planes() const {
  return {Eigen::Vector4d(1, 0, 0, x_min_m), Eigen::Vector4d(-1, 0, 0, -x_max_m),
          Eigen::Vector4d(0, 1, 0, y_min_m), Eigen::Vector4d(0, -1, 0, -y_max_m),
          Eigen::Vector4d(0, 0, 1, 0.0),     Eigen::Vector4d(0, 0, -1, -z_max_m)};
}

double SyntheticRoom::distance_to_nearest_surface(const Eigen::Vector3d& p_world) const {
  double best = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector4d& pl : planes()) {
    best = std::min(best, std::abs(pl.head<3>().dot(p_world) - pl[3]));
  }
  return best;
}

std::optional<RoomHit> ray_hit(const SyntheticRoom& room, const Eigen::Vector3d& origin_world,
                               const Eigen::Vector3d& direction_world) {
  const Box box = box_of(room);
  if (!inside(box, origin_world)) return std::nullopt;
  RoomHit hit;
  if (!cast(box, origin_world, direction_world, hit.range, hit.surface)) return std::nullopt;
  hit.p_world = origin_world + hit.range * direction_world;
  return hit;
}

double room_texture(const SyntheticRoom& room, RoomFace surface, double s_m, double t_m) {
  TextureSampler sampler(room.texture_seed);
  const int k = static_cast<int>(surface);
  return sampler.shapes(k, s_m, t_m) + sampler.noise(k, s_m, t_m);
}

namespace {

void check_render_args(const char* what, const SyntheticCamera& camera, int cam,
                       std::size_t out_size) {
  if (cam != 0 && cam != 1) {
    throw std::invalid_argument(std::string(what) + ": cam must be 0 (left) or 1 (right), got " +
                                std::to_string(cam));
  }
  if (camera.width_px <= 0 || camera.height_px <= 0 || !(camera.f_px > 0) ||
      camera.samples_per_axis < 1 || camera.samples_per_axis > 16) {
    throw std::invalid_argument(std::string(what) +
                                ": camera needs width, height, f > 0 and 1-16 samples");
  }
  const std::size_t n =
      static_cast<std::size_t>(camera.width_px) * static_cast<std::size_t>(camera.height_px);
  if (out_size != n) {
    throw std::invalid_argument(std::string(what) + ": out has " + std::to_string(out_size) +
                                " pixels, the image needs " + std::to_string(n));
  }
}

// Casts every pixel of rows [0, height) with the pose pose_of_row(v) and hands the unrounded
// gray value to sink(index, value); rows whose camera centre is outside the room are skipped
// (outside(v) is called for them instead).
template <typename PoseOfRow, typename Sink, typename Outside>
void render_rows(const SyntheticRoom& room, const SyntheticCamera& camera, int cam,
                 PoseOfRow&& pose_of_row, Sink&& sink, Outside&& outside) {
  const std::size_t w = static_cast<std::size_t>(camera.width_px);
  const std::size_t h = static_cast<std::size_t>(camera.height_px);
  const Box box = box_of(room);
  TextureSampler sampler(room.texture_seed);

  const int n = camera.samples_per_axis;
  const double inv_f = 1.0 / camera.f_px;
  const double inv_samples = 1.0 / static_cast<double>(n * n);
  // Rotated-grid supersampling: the n*n samples have n*n distinct x and n*n distinct y offsets
  // (a regular n x n grid has only n), so a near-vertical or near-horizontal edge moves the
  // pixel value in steps of 1/n^2 px instead of 1/n px.
  std::vector<double> offset(static_cast<std::size_t>(n * n));
  for (std::size_t k = 0; k < offset.size(); ++k) {
    offset[k] = (static_cast<double>(k) + 0.5) / static_cast<double>(n * n) - 0.5;
  }
  // Adaptive supersampling: the shapes at the pixel corners of the rows above (top) and below
  // (bottom) the current one; NaN where a corner ray leaves no hit (never equal).
  const bool adaptive = camera.adaptive && n > 1;
  std::vector<double> top(adaptive ? w + 1 : 0), bottom(adaptive ? w + 1 : 0);
  const SE3d* bottom_pose = nullptr;  // the pose `bottom` was sampled with, for row v - 1
  for (std::size_t v = 0; v < h; ++v) {
    const SE3d& T_world_cam = pose_of_row(v);
    const Eigen::Matrix3d R = T_world_cam.linear();
    const Eigen::Vector3d o =
        T_world_cam * Eigen::Vector3d(cam == 1 ? camera.baseline_m : 0.0, 0.0, 0.0);
    if (!inside(box, o)) {
      outside(v);
      bottom_pose = nullptr;
      continue;
    }
    // Ray direction of (u, v) = R * ((u - cx)/f, (v - cy)/f, 1) = c0 + u*du + v*dv.
    const Eigen::Vector3d du = R.col(0) * inv_f;
    const Eigen::Vector3d dv = R.col(1) * inv_f;
    const Eigen::Vector3d c0 = R.col(2) - camera.cx_px * du - camera.cy_px * dv;
    if (adaptive) {
      const auto corners = [&](std::vector<double>& out_row, double y) {
        for (std::size_t u = 0; u <= w; ++u) {
          const Eigen::Vector3d d = c0 + (static_cast<double>(u) - 0.5) * du + y * dv;
          double range = 0, s = 0, t = 0;
          RoomFace surface = RoomFace::kFloor;
          out_row[u] = std::numeric_limits<double>::quiet_NaN();
          if (!cast(box, o, d, range, surface)) continue;
          surface_coords(surface, o + range * d, s, t);
          out_row[u] = sampler.shapes(static_cast<int>(surface), s, t);
        }
      };
      const double vc = static_cast<double>(v);
      if (bottom_pose == &T_world_cam) {
        top.swap(bottom);  // the row above was seen from the same pose: share its corners
      } else {
        corners(top, vc - 0.5);
      }
      corners(bottom, vc + 0.5);
      bottom_pose = &T_world_cam;
    }
    for (std::size_t u = 0; u < w; ++u) {
      const double uc = static_cast<double>(u), vc = static_cast<double>(v);
      double range = 0;
      RoomFace surface = RoomFace::kFloor;
      double s = 0, t = 0;
      if (adaptive && top[u] == top[u + 1] && top[u] == bottom[u] && top[u] == bottom[u + 1]) {
        double value = top[u];
        const Eigen::Vector3d d = c0 + uc * du + vc * dv;
        if (cast(box, o, d, range, surface)) {
          surface_coords(surface, o + range * d, s, t);
          value += sampler.noise(static_cast<int>(surface), s, t);
        }
        sink(v * w + u, value);
        continue;
      }
      if (n == 1) {
        // One sample at the pixel centre: the shapes and the noise share its ray (the same
        // value the general path computes, with one cast instead of two).
        const Eigen::Vector3d d = c0 + uc * du + vc * dv;
        double value = 0.0;
        if (cast(box, o, d, range, surface)) {
          surface_coords(surface, o + range * d, s, t);
          value = sampler.shapes(static_cast<int>(surface), s, t) +
                  sampler.noise(static_cast<int>(surface), s, t);
        }
        sink(v * w + u, value);
        continue;
      }
      double sum = 0.0;
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) {
          const double su = uc + offset[static_cast<std::size_t>(a * n + b)];
          const double sv = vc + offset[static_cast<std::size_t>(b * n + n - 1 - a)];
          const Eigen::Vector3d d = c0 + su * du + sv * dv;
          if (!cast(box, o, d, range, surface)) continue;
          surface_coords(surface, o + range * d, s, t);
          sum += sampler.shapes(static_cast<int>(surface), s, t);
        }
      }
      double value = sum * inv_samples;
      const Eigen::Vector3d d = c0 + uc * du + vc * dv;
      if (cast(box, o, d, range, surface)) {
        surface_coords(surface, o + range * d, s, t);
        value += sampler.noise(static_cast<int>(surface), s, t);
      }
      sink(v * w + u, value);
    }
  }
}

}  // namespace

void render_room(const SyntheticRoom& room, const SyntheticCamera& camera, const SE3d& T_world_cam,
                 int cam, std::span<std::uint8_t> out) {
  check_render_args("render_room", camera, cam, out.size());
  const std::size_t w = static_cast<std::size_t>(camera.width_px);
  render_rows(
      room, camera, cam, [&](std::size_t) -> const SE3d& { return T_world_cam; },
      [&](std::size_t i, double value) {
        out[i] = static_cast<std::uint8_t>(std::clamp(value, 0.0, 255.0) + 0.5);
      },
      [&](std::size_t v) {
        std::fill(out.begin() + static_cast<std::ptrdiff_t>(v * w),
                  out.begin() + static_cast<std::ptrdiff_t>((v + 1) * w), std::uint8_t{0});
      });
}

void render_room_accumulate(const SyntheticRoom& room, const SyntheticCamera& camera,
                            std::span<const SE3d> T_world_cam_rows, int cam, float weight,
                            std::span<float> accum) {
  check_render_args("render_room_accumulate", camera, cam, accum.size());
  const std::size_t h = static_cast<std::size_t>(camera.height_px);
  if (T_world_cam_rows.size() != 1 && T_world_cam_rows.size() != h) {
    throw std::invalid_argument("render_room_accumulate: needs 1 pose or one per row (" +
                                std::to_string(h) + "), got " +
                                std::to_string(T_world_cam_rows.size()));
  }
  const bool per_row = T_world_cam_rows.size() == h && h > 1;
  render_rows(
      room, camera, cam,
      [&](std::size_t v) -> const SE3d& { return T_world_cam_rows[per_row ? v : 0]; },
      [&](std::size_t i, double value) { accum[i] += weight * static_cast<float>(value); },
      [](std::size_t) {});
}

std::vector<StampedPose> synthetic_trajectory(const SyntheticRoom& room, int n, double rate_hz,
                                              TimeNs t0_ns) {
  if (n < 0 || !(rate_hz > 0)) {
    throw std::invalid_argument("synthetic_trajectory: needs n >= 0 and rate_hz > 0");
  }
  const double size_x = room.x_max_m - room.x_min_m, size_y = room.y_max_m - room.y_min_m;
  if (!(size_x >= 2.0 && size_y >= 2.0 && room.z_max_m >= 1.0)) {
    throw std::invalid_argument("synthetic_trajectory: the room must be at least 2 x 2 x 1 m");
  }
  constexpr double kPi = std::numbers::pi;
  constexpr double kDeg = kPi / 180.0;
  const double cx = 0.5 * (room.x_min_m + room.x_max_m);
  const double cy = 0.5 * (room.y_min_m + room.y_max_m);
  const double ax = std::min(0.8, 0.2 * size_x), ay = std::min(0.5, 0.2 * size_y);
  const double z0 = std::min(1.5, 0.5 * room.z_max_m);
  const double bob = std::min(0.1, 0.2 * room.z_max_m);
  std::vector<StampedPose> out;
  out.reserve(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double t_s = static_cast<double>(k) / rate_hz;
    const double phase = 2.0 * kPi * t_s / kSyntheticTrajectoryPeriodS;
    const Eigen::Vector3d p(cx + ax * std::cos(phase), cy + ay * std::sin(phase),
                            z0 + bob * std::sin(2.0 * phase));
    const double yaw = kPi / 2 + 40.0 * kDeg * std::sin(phase);  // heading from +x, toward +y
    const double pitch = 8.0 * kDeg * std::sin(2.0 * phase + 0.5);
    const double roll = 3.0 * kDeg * std::sin(3.0 * phase);
    // Level camera with heading `yaw`: columns x right, y down, z forward in world coordinates.
    Eigen::Matrix3d R0;
    R0.col(2) = Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0.0);
    R0.col(0) = Eigen::Vector3d(std::sin(yaw), -std::cos(yaw), 0.0);
    R0.col(1) = Eigen::Vector3d(0.0, 0.0, -1.0);
    const Eigen::Matrix3d R = R0 * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
                              Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ());
    StampedPose pose;
    pose.t_ns = t0_ns + static_cast<TimeNs>(std::llround(t_s * 1e9));
    pose.T_world_body = SE3d::Identity();
    pose.T_world_body.linear() = R;
    pose.T_world_body.translation() = p;
    out.push_back(pose);
  }
  return out;
}

RigCalibration synthetic_rig(const SyntheticCamera& camera) {
  RigCalibration rig;
  for (std::size_t i = 0; i < 2; ++i) {
    CameraCalibration& c = rig.cams[i];
    c.name = i == 0 ? "cam0" : "cam1";
    c.width_px = camera.width_px;
    c.height_px = camera.height_px;
    c.fx = c.fy = camera.f_px;
    c.cx = camera.cx_px;
    c.cy = camera.cy_px;
    c.distortion = {0.0, 0.0, 0.0, 0.0};
  }
  rig.cams[1].T_body_cam.translation() = Eigen::Vector3d(camera.baseline_m, 0.0, 0.0);
  return rig;
}

Image render_room_image(const SyntheticRoom& room, const SyntheticCamera& camera,
                        const SE3d& T_world_cam, int cam) {
  Image img = Image::allocate(camera.width_px, camera.height_px, PixelFormat::kGray8);
  render_room(
      room, camera, T_world_cam, cam,
      std::span<std::uint8_t>(img.mutable_data(), static_cast<std::size_t>(camera.width_px) *
                                                      static_cast<std::size_t>(camera.height_px)));
  return img;
}

}  // namespace wallar::dsp
