// SPDX-License-Identifier: Apache-2.0
/// @file headset_renderer.hpp
/// @brief What the wearer sees: per eye the camera image, undistorted in the shader, with the
/// wall model drawn in that eye's camera from the tracked pose (translucent quads clipped to
/// their extent polygons, outlined, coloured by id, front side only), a grid on the floor and a
/// small HUD; side by side on the display, optionally pre-distorted for the headset's lenses.
///
/// Pixel conventions: image pixel (u, v) has its centre at integer coordinates (OpenCV's), an
/// eye's viewport keeps the camera image's aspect ratio (letter-boxed in its half), so a world
/// point's overlay lands exactly where the camera model projects it.
///
/// Threading: construct, draw and destroy on the thread that opened the DisplayOutput (its GL
/// context is current there). draw() reads the frame's images and the wall model without
/// keeping references; the caller hands it the newest snapshot (it never waits for tracking).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "wallar/core/image.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/drivers/display/display_output.hpp"

namespace wallar::display {

/// A camera's pinhole model with radial-tangential distortion (k1, k2, p1, p2), as calibrated.
struct EyeCamera {
  int width_px = 0;
  int height_px = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  //!< [px]
  std::array<double, 4> radtan{};                 //!< k1, k2, p1, p2
};

struct EyeInput {
  Image image;  //!< kGray8 camera image (raw, distorted); empty or another format: black
  EyeCamera camera;
  SE3d T_world_cam = SE3d::Identity();
};

/// The HUD's lines (tracking state, rate, wall count, degraded mode).
struct HudState {
  std::string tracking = "tracking";  //!< "tracking", "lost", "initialising", ...
  double fps = 0.0;
  int walls = 0;
  std::string degraded;  //!< empty = nominal; e.g. "camera lost: IMU orientation only"
  /// The camera is lost and the image is the last one it gave: drawn dark red with no overlay
  /// and "CAMERA LOST" on the HUD, so nobody takes a still picture for the world (video
  /// see-through) nor sees walls swim over it.
  bool image_frozen = false;
};

struct HeadsetFrame {
  TimeNs t_ns = 0;  //!< the camera frame's time stamp
  TimeNs capture_t_ns =
      0;  //!< CLOCK_MONOTONIC time it was captured/published (latency); 0 = unknown
  std::array<EyeInput, 2> eyes;
  bool pose_valid = true;  //!< false: camera images and HUD only
  const WallModel* walls = nullptr;
  HudState hud;
};

struct RendererOptions {
  bool undistort = true;  //!< undistort the camera images (the overlay assumes it)
  bool hud = true;
  bool floor_grid = true;
  bool outlines = true;
  float wall_alpha = 0.35f;  //!< fill opacity of the wall quads
  double grid_spacing_m = 0.5;
  double near_m = 0.05, far_m = 100.0;
  /// Lens pre-distortion per eye, r_src = r (1 + k1 r^2 + k2 r^4) with r in half-heights of
  /// the eye's viewport; both 0 = off (drawn straight to the display).
  double lens_k1 = 0.0, lens_k2 = 0.0;
};

struct RenderTiming {
  TimeNs render_ns = 0;     //!< from draw() until present() returned (kms: with the flip wait)
  TimeNs present_t_ns = 0;  //!< when it reached the display
  TimeNs latency_ns = -1;   //!< present_t_ns - capture_t_ns; -1 when unknown
  bool presented = false;   //!< false: the output failed (see DisplayOutput::last_error)
};

/// An eye's viewport in display pixels, top-left origin.
struct EyeViewport {
  int x = 0, y = 0, width = 0, height = 0;
};

/// Where eye `eye` (0 left, 1 right) of an image of this size goes on a display of this size.
EyeViewport eye_viewport(int display_width_px, int display_height_px, int eye, int image_width_px,
                         int image_height_px);

class HeadsetRenderer {
 public:
  /// Compiles the shaders, allocates every buffer and draws one frame with every program and
  /// state, not presented (a software rasteriser compiles a shader's code at its first draw:
  /// the first real frame then compiles nothing); `cameras`, those whose images it will draw,
  /// size the image textures once (width 0: allocated at the first image). Throws DisplayError
  /// on GL failure.
  HeadsetRenderer(DisplayOutput& output, const RendererOptions& options,
                  const std::array<EyeCamera, 2>& cameras = {});
  ~HeadsetRenderer();
  HeadsetRenderer(const HeadsetRenderer&) = delete;
  HeadsetRenderer& operator=(const HeadsetRenderer&) = delete;

  /// Draws both eyes and presents. Images of a new size re-allocate their textures once.
  /// A non-empty `capture_rgba` (width * height * 4 bytes of the output) receives the finished
  /// frame, top row first, read back before it is presented (after a swap the back buffer's
  /// contents are undefined on KMS).
  RenderTiming draw(const HeadsetFrame& frame, std::span<std::uint8_t> capture_rgba = {});

  [[nodiscard]] const RendererOptions& options() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wallar::display
