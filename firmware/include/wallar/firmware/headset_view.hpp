// SPDX-License-Identifier: Apache-2.0
/// @file headset_view.hpp
/// @brief The visualization module's drawing side: a display output from the board file, the
/// headset renderer on it, stereo frames with their body pose turned into per-eye views, every
/// Nth frame written as PNG, and render-time / camera-to-display latency statistics.
///
/// Frames: `T_world_body` is the body (EuRoC: IMU) pose in the wall model's world; each eye's
/// camera pose is T_world_body * T_body_cam from the rig calibration.
///
/// Threading: construct, use and destroy on one thread (the display's GL context is current
/// there); it keeps no reference to the frames or models it is given.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/core/stereo_frame.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/drivers/display/headset_renderer.hpp"
#include "wallar/firmware/board.hpp"

namespace wallar::firmware {

using DisplayOpener =
    std::function<std::unique_ptr<display::DisplayOutput>(const display::DisplayOptions&)>;

struct HeadsetViewOptions {
  display::DisplayOptions display;
  display::RendererOptions renderer;
  std::filesystem::path png_dir;               //!< empty: no PNG frames
  int png_every = 1;                           //!< write frames 0, N, 2N, ...
  DisplayOpener open = display::open_display;  //!< tests inject failing outputs here
};

/// The view options of a board file's `display:` section: output and lens pre-distortion
/// (throws DisplayError for an unknown backend).
HeadsetViewOptions view_options(const DisplayConfig& board);

struct HeadsetViewStats {
  std::uint64_t frames = 0;
  std::uint64_t written = 0;
  std::uint64_t present_failures = 0;
  std::uint64_t on_screen = 0;  //!< frames the display confirmed (kms: mode set + page flips)
  TimeNs last_t_ns = -1;        //!< the camera time of the last frame shown
  std::vector<std::int64_t> render_ns;   //!< per frame (the first 32768)
  std::vector<std::int64_t> latency_ns;  //!< per frame with a capture time (the first 32768)
  std::vector<std::string> written_files;
};

class HeadsetView {
 public:
  /// Opens the display and compiles the renderer; throws DisplayError (one line).
  HeadsetView(const RigCalibration& rig, const HeadsetViewOptions& options);
  ~HeadsetView();
  HeadsetView(const HeadsetView&) = delete;
  HeadsetView& operator=(const HeadsetView&) = delete;

  /// Draws `frame` seen from `T_world_body` (ignored when !pose_valid) with `walls` (may be
  /// null) and the HUD; writes it as PNG when its turn comes. Returns false when the output
  /// failed (counted; the caller may re-open).
  bool show(const StereoFrame& frame, TimeNs capture_t_ns, const SE3d& T_world_body,
            bool pose_valid, const WallModel* walls, const display::HudState& hud);

  [[nodiscard]] const HeadsetViewStats& stats() const { return stats_; }
  [[nodiscard]] std::string describe() const;
  /// Why the last show() returned false.
  [[nodiscard]] const std::string& last_error() const;

 private:
  RigCalibration rig_;
  HeadsetViewOptions options_;
  std::unique_ptr<display::DisplayOutput> output_;
  std::unique_ptr<display::HeadsetRenderer> renderer_;
  std::vector<std::uint8_t> capture_rgba_;  // a PNG frame, read back before present
  HeadsetViewStats stats_;
};

/// The per-eye camera model of a calibrated camera (radial-tangential; other models are
/// drawn without undistortion and say so by returning false).
bool eye_camera(const CameraCalibration& calib, display::EyeCamera& out);

}  // namespace wallar::firmware
