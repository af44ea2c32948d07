// SPDX-License-Identifier: Apache-2.0
/// @file synthetic_room.hpp
/// @brief A textured box room rendered to rectified stereo images along a known trajectory:
/// ground truth for the stereo tracker (ATE against the trajectory, map points against walls).
///
/// The room is an axis-aligned box in world coordinates (z up, floor at z = 0). Each of its six
/// surfaces carries a different procedural texture, a function of (texture_seed, surface, the
/// 2-D surface coordinates in metres) only: random rectangles and discs of random gray levels in
/// three cell sizes (0.45, 0.22, 0.11 m) painted large to small over low-contrast value noise.
/// Nothing repeats, so stereo matching is unambiguous, and the shapes' corners give a FAST
/// detector plenty of well-spread corners at 1-6 m. Images are supersampled (samples_per_axis^2
/// rays per pixel on a rotated grid), so edges and corners sit at sub-pixel-accurate positions.
///
/// Threading: pure functions and value types; render_room may run concurrently on different
/// output buffers.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/core/image.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"

namespace wallar::dsp {

/// An axis-aligned box room in world coordinates, z up, floor at z = 0.
struct SyntheticRoom {
  double x_min_m = -3, x_max_m = 3, y_min_m = -4, y_max_m = 4, z_max_m = 3;
  std::uint64_t texture_seed = 1;

  /// The 6 surfaces as planes n.p - d = 0 with n pointing INTO the room (toward the viewer),
  /// in the order of RoomFace: x_min, x_max, y_min, y_max, floor, ceiling.
  [[nodiscard]] std::array<Eigen::Vector4d, 6> planes() const;  // (nx, ny, nz, d)
  /// Distance from p_world to the nearest of the six (infinite) surface planes [m]; for a point
  /// inside the room this is its clearance.
  [[nodiscard]] double distance_to_nearest_surface(const Eigen::Vector3d& p_world) const;
};

/// Index of a surface in SyntheticRoom::planes().
enum class RoomFace : int { kXMin = 0, kXMax, kYMin, kYMax, kFloor, kCeiling };

/// A rectified pinhole stereo pair without distortion; the right camera sits at +baseline_m
/// along the left camera's x axis with the same orientation.
struct SyntheticCamera {
  int width_px = 752, height_px = 480;
  double f_px = 450, cx_px = 375.5, cy_px = 239.5, baseline_m = 0.11;
  /// Supersampling: samples_per_axis^2 rays per pixel on a rotated grid (samples_per_axis^2
  /// distinct offsets along each axis; 1 = the pixel centre only).
  int samples_per_axis = 2;
  /// Adaptive supersampling: the shapes are first sampled at the pixel corners (each corner
  /// shared by four pixels); a pixel whose four corners agree (inside one shape, or on the
  /// background) takes that value with no more rays, the others get the samples_per_axis^2.
  /// About twice as fast at samples_per_axis = 2; the image differs from full supersampling
  /// only where a shape's corner pokes into a pixel without covering one of the pixel's corners
  /// (shapes are wider than a pixel at room distances). Off by default.
  bool adaptive = false;
};

/// Where a ray from origin_world along direction_world (any length > 0) leaves the room: the
/// nearest surface hit. nullopt when the origin is not inside the room or the direction is 0.
struct RoomHit {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  double range = 0;  //!< distance along the ray in units of |direction_world|
  RoomFace surface = RoomFace::kXMin;
};
[[nodiscard]] std::optional<RoomHit> ray_hit(const SyntheticRoom& room,
                                             const Eigen::Vector3d& origin_world,
                                             const Eigen::Vector3d& direction_world);

/// The texture's gray level (0-255, unrounded) on `surface` at surface coordinates (s_m, t_m):
/// (y, z) on the x walls, (x, z) on the y walls, (x, y) on the floor and the ceiling. Point
/// samples, no filtering; render_room averages them.
[[nodiscard]] double room_texture(const SyntheticRoom& room, RoomFace surface, double s_m,
                                  double t_m);

/// Renders the left (cam = 0) or right (cam = 1, shifted +baseline along the camera's x) 8-bit
/// gray image seen by a camera whose LEFT camera pose is T_world_cam (camera x right, y down,
/// z forward) into `out` (width*height bytes, row-major, stride = width). Pixel (u, v) has its
/// centre at u, v (so the ray of pixel centre (u, v) is ((u - cx)/f, (v - cy)/f, 1)). Pixels
/// whose rays leave no hit (camera outside the room) are 0.
/// Throws std::invalid_argument for cam not 0/1, a bad camera or an `out` of the wrong size.
void render_room(const SyntheticRoom& room, const SyntheticCamera& camera, const SE3d& T_world_cam,
                 int cam, std::span<std::uint8_t> out);

/// Adds weight * the unrounded gray value (the value render_room rounds) of every pixel into
/// `accum` (width*height floats, row-major): the building block of exposure integration
/// (synthetic_motion.hpp averages sub-frames). T_world_cam_rows holds one LEFT camera pose for the
/// whole image (global shutter) or one per row (rolling shutter: row v seen from
/// T_world_cam_rows[v]). Rows seen from outside the room add nothing.
/// Throws std::invalid_argument as render_room does, or for a pose count other than 1 or height.
void render_room_accumulate(const SyntheticRoom& room, const SyntheticCamera& camera,
                            std::span<const SE3d> T_world_cam_rows, int cam, float weight,
                            std::span<float> accum);

/// A smooth closed trajectory inside the room: n poses at rate_hz from t0_ns, T_world_body of the
/// LEFT camera (camera frame: x right, y down, z forward). The camera circles an ellipse of about
/// 0.8 m x 0.5 m semi-axes (smaller in small rooms) around the room centre at 1.5 m height (bobbing
/// +-0.1 m) once every kSyntheticTrajectoryPeriodS, looking roughly horizontally toward the +y
/// wall with its heading swinging +-40 deg, pitch +-8 deg and roll +-3 deg. Deterministic and
/// periodic. Throws std::invalid_argument for n < 0, rate_hz <= 0 or a room under 2 m x 2 m x 1 m.
/// The rig that `camera` describes, as a calibration (no distortion; the right camera
/// baseline_m along the left one's +x; body = left camera): what the tracker is given.
[[nodiscard]] RigCalibration synthetic_rig(const SyntheticCamera& camera);

/// render_room into a new 8-bit gray Image.
[[nodiscard]] Image render_room_image(const SyntheticRoom& room, const SyntheticCamera& camera,
                                      const SE3d& T_world_cam, int cam);

inline constexpr double kSyntheticTrajectoryPeriodS = 20.0;
[[nodiscard]] std::vector<StampedPose> synthetic_trajectory(const SyntheticRoom& room, int n,
                                                            double rate_hz, TimeNs t0_ns = 0);

}  // namespace wallar::dsp
