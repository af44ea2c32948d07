// SPDX-License-Identifier: Apache-2.0
/// @file headset_view.cpp
/// @brief Board display -> renderer -> PNG frames and statistics.
#include "wallar/firmware/headset_view.hpp"

#include <cstdio>

#include "wallar/drivers/recording/euroc.hpp"

namespace wallar::firmware {
namespace {
constexpr std::size_t kKeptFrames = 1 << 15;
}  // namespace

HeadsetViewOptions view_options(const DisplayConfig& board) {
  HeadsetViewOptions o;
  o.display.backend = display::parse_display_backend(board.backend);
  o.display.card = board.card;
  o.display.connector = board.connector;
  o.display.width_px = board.width_px;
  o.display.height_px = board.height_px;
  o.renderer.lens_k1 = board.lens_k1;
  o.renderer.lens_k2 = board.lens_k2;
  return o;
}

bool eye_camera(const CameraCalibration& calib, display::EyeCamera& out) {
  out.width_px = calib.width_px;
  out.height_px = calib.height_px;
  out.fx = calib.fx;
  out.fy = calib.fy;
  out.cx = calib.cx;
  out.cy = calib.cy;
  out.radtan = {};
  if (calib.distortion_model != "radial-tangential" && calib.distortion_model != "radtan") {
    return false;
  }
  for (std::size_t i = 0; i < 4 && i < calib.distortion.size(); ++i) {
    out.radtan[i] = calib.distortion[i];
  }
  return true;
}

HeadsetView::HeadsetView(const RigCalibration& rig, const HeadsetViewOptions& options)
    : rig_(rig), options_(options) {
  if (options_.png_every < 1) options_.png_every = 1;
  output_ = options_.open(options_.display);
  std::array<display::EyeCamera, 2> cameras;
  for (std::size_t eye = 0; eye < 2; ++eye) eye_camera(rig_.cams[eye], cameras[eye]);
  renderer_ = std::make_unique<display::HeadsetRenderer>(*output_, options_.renderer, cameras);
  if (!options_.png_dir.empty()) {
    std::filesystem::create_directories(options_.png_dir);
    capture_rgba_.resize(static_cast<std::size_t>(output_->width_px()) * output_->height_px() * 4);
  }
  // Per-frame figures for about 15 minutes at 30 Hz; later frames are counted, not kept.
  stats_.render_ns.reserve(kKeptFrames);
  stats_.latency_ns.reserve(kKeptFrames);
}

HeadsetView::~HeadsetView() = default;

std::string HeadsetView::describe() const { return output_->describe(); }
const std::string& HeadsetView::last_error() const { return output_->last_error(); }

bool HeadsetView::show(const StereoFrame& frame, TimeNs capture_t_ns, const SE3d& T_world_body,
                       bool pose_valid, const WallModel* walls, const display::HudState& hud) {
  display::HeadsetFrame view;
  view.t_ns = frame.t_ns;
  view.capture_t_ns = capture_t_ns;
  view.pose_valid = pose_valid;
  view.walls = walls;
  view.hud = hud;
  const CameraFrame* cams[2] = {&frame.left, &frame.right};
  for (std::size_t eye = 0; eye < 2; ++eye) {
    display::EyeInput& in = view.eyes[eye];
    eye_camera(rig_.cams[eye], in.camera);
    in.image = cams[eye]->image;
    in.T_world_cam = T_world_body * rig_.cams[eye].T_body_cam;
  }
  const auto every = static_cast<std::uint64_t>(options_.png_every);
  const bool png_due = !options_.png_dir.empty() && stats_.frames % every == 0;
  const display::RenderTiming t = renderer_->draw(
      view, png_due ? std::span<std::uint8_t>(capture_rgba_) : std::span<std::uint8_t>());
  ++stats_.frames;
  if (!t.presented) {
    ++stats_.present_failures;
    return false;
  }
  stats_.last_t_ns = frame.t_ns;
  stats_.on_screen = output_->frames_on_screen();
  if (stats_.render_ns.size() < kKeptFrames) stats_.render_ns.push_back(t.render_ns);
  if (t.latency_ns >= 0 && stats_.latency_ns.size() < kKeptFrames) {
    stats_.latency_ns.push_back(t.latency_ns);
  }
  if (png_due) {
    char name[64];
    std::snprintf(name, sizeof name, "view_%06llu.png",
                  static_cast<unsigned long long>(stats_.frames - 1));
    const std::filesystem::path path = options_.png_dir / name;
    recording::save_png(
        path, display::rgba_to_rgb(capture_rgba_, output_->width_px(), output_->height_px()));
    stats_.written_files.push_back(path.string());
    ++stats_.written;
  }
  return true;
}

}  // namespace wallar::firmware
