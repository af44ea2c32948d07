// SPDX-License-Identifier: Apache-2.0
/// @file cmd_render.cpp
/// @brief `wallar render RECORDING --out DIR [--walls walls.json]`: the headset view of a
/// recording, offline. Without --walls it tracks the recording and finds the walls in the map
/// as the firmware would (gravity-aligned world, z up); every Nth frame is written as PNG.
///
/// --realtime replays the recording at its own pace through the tracking system while the
/// visualization thread draws the newest frame (render time, camera-to-display latency).
///
/// Frames: the world is the tracker's gravity-aligned world (`wallar track --gravity-aligned`);
/// a walls.json given with --walls must be in that frame (the one this command writes is).
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "percentiles.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/headset_view.hpp"
#include "wallar/firmware/live_view.hpp"
#include "wallar/firmware/report.hpp"
#include "wallar/firmware/track_recording.hpp"

namespace wallar::cli {
namespace {

namespace fs = std::filesystem;

struct RenderArgs {
  std::string recording;
  std::string out;
  std::string walls;
  std::string board;
  int every = 0;  // 0: offline every frame, real time none
  bool realtime = false;
  double rate = 1.0;
  int width_px = 0, height_px = 0;
  std::vector<double> lens;
  bool json = false;
};

// Inlier band of the tracker's map (its points are within ~2 cm of the surfaces, docs/results.md).
constexpr double kMapThresholdM = 0.04;

std::int64_t render_clock_ns() { return monotonic_now_ns(); }

/// The stereo pair of the recording at left time `t_ns` (right: the nearest within 2 ms).
StereoFrame load_pair(const recording::EurocRecording& rec, TimeNs t_ns, std::uint64_t sequence) {
  StereoFrame f;
  f.t_ns = t_ns;
  f.sequence = sequence;
  CameraFrame* out[2] = {&f.left, &f.right};
  for (std::size_t c = 0; c < 2; ++c) {
    const auto& frames = rec.cams[c].frames;
    const auto it =
        std::lower_bound(frames.begin(), frames.end(), t_ns - 2 * kNsPerMs,
                         [](const recording::FrameEntry& e, TimeNs t) { return e.t_ns < t; });
    if (it == frames.end() || std::llabs(it->t_ns - t_ns) > 2 * kNsPerMs) continue;
    out[c]->t_ns = it->t_ns;
    out[c]->image = recording::load_png_gray(
        rec.cams[c].image_path(*it), rec.cams[c].calib.width_px, rec.cams[c].calib.height_px);
  }
  return f;
}

/// Replays the recording at `rate` through the tracking system (mapping on its thread, as on
/// the device) while the visualization thread draws the newest frame: the end-to-end latency.
int run_realtime(const RenderArgs& a, const recording::EurocRecording& rec,
                 const firmware::BoardConfig& board, const firmware::TrackRecordingResult& offline,
                 const WallModel& walls, const firmware::HeadsetViewOptions& view_options) {
  const RigCalibration rig = rec.rig();
  firmware::TrackingAndMapping system(rig, firmware::tracking_options(board.tracking),
                                  &render_clock_ns);
  firmware::LiveView live(rig, view_options, walls, rig.cams[0].rate_hz);
  struct Sink final : source::SensorSink {
    Sink(firmware::TrackingAndMapping& s, firmware::LiveView& v, const SE3d& world, const SE3d& rect)
        : system(s), view(v), T_world_tracker(world), T_rect_body(rect.inverse()) {
      track_ns.reserve(1 << 15);
    }
    void on_imu(const ImuSample& sample) override { system.on_imu(sample); }
    void on_stereo(const StereoFrame& frame) override {
      const dsp::TrackResult r = system.on_stereo(frame);
      if (track_ns.size() < track_ns.capacity()) track_ns.push_back(r.times.total_ns);
      view.post(
          {frame, frame.left.publish_t_ns, T_world_tracker * r.T_world_cam * T_rect_body, r.state});
    }
    firmware::TrackingAndMapping& system;
    firmware::LiveView& view;
    SE3d T_world_tracker, T_rect_body;
    std::vector<std::int64_t> track_ns;
  } sink(system, live, offline.T_world_tracker, offline.T_body_rect);
  source::ReplayOptions replay;
  replay.rate = a.rate;
  const source::ReplayStats replay_stats =
      source::ReplaySource(rec, replay).run(sink, stop_requested());
  system.finish();
  const firmware::LiveViewStats s = live.stop();
  const Percentiles render = percentiles(s.view.render_ns);
  const Percentiles latency = percentiles(s.view.latency_ns);
  const Percentiles track = percentiles(sink.track_ns);
  nlohmann::json summary = {{"recording", a.recording},
                            {"mode", "realtime"},
                            {"rate", a.rate},
                            {"display", s.display},
                            {"posted", s.posted},
                            {"drawn", s.view.frames},
                            {"skipped", s.skipped},
                            {"present_failures", s.view.present_failures},
                            {"written", s.view.written},
                            {"walls", walls.walls.size()},
                            {"tracking_time", to_json(track)},
                            {"render_time", to_json(render)},
                            {"camera_to_display_latency", to_json(latency)},
                            {"replay", firmware::to_json(replay_stats)}};
  std::ofstream(fs::path(a.out) / "render_summary.json") << summary.dump(2) << "\n";
  if (a.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::printf(
        "wallar render --realtime: %llu frames posted at %.2gx, %llu drawn on %s, %llu "
        "skipped (newer frame waiting)\n",
        static_cast<unsigned long long>(s.posted), a.rate,
        static_cast<unsigned long long>(s.view.frames), s.display.c_str(),
        static_cast<unsigned long long>(s.skipped));
    std::printf("  tracking per frame: p50 %.2f ms, p99 %.2f; render: p50 %.2f ms, p99 %.2f\n",
                track.p50_ms, track.p99_ms, render.p50_ms, render.p99_ms);
    std::printf("  camera-to-display latency: p50 %.2f ms, p99 %.2f, max %.2f\n", latency.p50_ms,
                latency.p99_ms, latency.max_ms);
  }
  return stop_requested().load() ? kExitInterrupted : kExitOk;
}

int run_render(const RenderArgs& a) {
  const recording::EurocRecording rec = recording::read_euroc(a.recording);
  const firmware::BoardConfig board =
      a.board.empty() ? firmware::BoardConfig{} : firmware::load_board(a.board);
  // The whole recording tracked (map on the tracking thread: repeatable), as `wallar track`.
  firmware::TrackRecordingOptions track_options;
  track_options.tracking = firmware::tracking_options(board.tracking);
  track_options.tracking.mapping_thread = false;
  track_options.gravity_aligned = true;
  const firmware::TrackRecordingResult track =
      firmware::track_recording(rec, track_options, stop_requested());

  // The walls: given, or found in the map with gravity (world z up) as the firmware would.
  WallModel walls;
  nlohmann::json walls_json;
  if (!a.walls.empty()) {
    walls = firmware::read_walls_json(a.walls);
    walls_json = {{"source", a.walls}};
  } else {
    const dsp::RoomConfig config = dsp::room_config_for_map(
        track.keyframe_centres, Eigen::Vector3d(0.0, 0.0, -1.0), kMapThresholdM);
    dsp::RoomEstimator estimator(std::max<std::size_t>(track.map.size(), 1));
    const dsp::RoomResult room = estimator.estimate(track.map, config);
    walls = room.model;
    walls_json = firmware::to_json(room);
    walls_json["frame"] =
        "world: the first body pose turned so z is up (wallar track --gravity-aligned)";
  }
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) throw_input_error(a.out, 0, "cannot create output folder: " + ec.message());
  if (a.walls.empty()) std::ofstream(fs::path(a.out) / "walls.json") << walls_json.dump(2) << "\n";

  firmware::HeadsetViewOptions view_options = firmware::view_options(board.display);
  view_options.display.backend = display::DisplayBackend::kHeadless;  // offline: never the panel
  if (a.width_px > 0) view_options.display.width_px = a.width_px;
  if (a.height_px > 0) view_options.display.height_px = a.height_px;
  if (a.lens.size() == 2) {
    view_options.renderer.lens_k1 = a.lens[0];
    view_options.renderer.lens_k2 = a.lens[1];
  }
  if (a.realtime) {
    if (a.every > 0) {
      view_options.png_dir = a.out;
      view_options.png_every = a.every;
    }
    return run_realtime(a, rec, board, track, walls, view_options);
  }
  view_options.png_dir = a.out;
  view_options.png_every = std::max(1, a.every);
  const RigCalibration rig = rec.rig();
  firmware::HeadsetView view(rig, view_options);
  const double fps = rig.cams[0].rate_hz;
  for (std::size_t i = 0; i < track.frames.size() && !stop_requested().load(); ++i) {
    const dsp::TrackResult& r = track.frames[i];
    const StereoFrame pair = load_pair(rec, r.t_ns, i);
    display::HudState hud;
    hud.tracking = dsp::to_string(r.state);
    hud.fps = fps;
    hud.walls = static_cast<int>(walls.walls.size());
    const bool pose_valid = r.state == dsp::TrackingState::kTracking;
    if (!view.show(pair, 0, track.poses[i].T_world_body, pose_valid, &walls, hud)) {
      std::fprintf(stderr, "wallar: error: display: %s: %s\n", view.describe().c_str(),
                   view.last_error().c_str());
      return kExitFailure;
    }
  }
  const firmware::HeadsetViewStats& s = view.stats();
  const Percentiles render = percentiles(s.render_ns);
  nlohmann::json summary = {{"recording", a.recording},    {"display", view.describe()},
                            {"frames", s.frames},          {"written", s.written},
                            {"walls", walls.walls.size()}, {"render_time", to_json(render)},
                            {"outputs", s.written_files}};
  std::ofstream(fs::path(a.out) / "render_summary.json") << summary.dump(2) << "\n";
  if (a.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::printf("wallar render: %llu frames on %s, %llu written to %s/, %zu surfaces\n",
                static_cast<unsigned long long>(s.frames), view.describe().c_str(),
                static_cast<unsigned long long>(s.written), a.out.c_str(), walls.walls.size());
    std::printf("  render time per stereo frame: mean %.2f ms, p50 %.2f, p99 %.2f, max %.2f\n",
                render.mean_ms, render.p50_ms, render.p99_ms, render.max_ms);
  }
  return stop_requested().load() ? kExitInterrupted : kExitOk;
}

}  // namespace

void add_render_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand(
      "render", "Render a recording's headset view (camera images with the wall model) as PNGs");
  cmd->add_option("recording", args->recording, "EuRoC-layout recording (ROOT or ROOT/mav0)")
      ->required();
  cmd->add_option("--out", args->out, "folder for view_NNNNNN.png, walls.json, render_summary.json")
      ->required();
  cmd->add_option("--walls", args->walls,
                  "wall model (wallar walls / render JSON) in the tracker's gravity-aligned world; "
                  "default: track and find the walls")
      ->check(CLI::ExistingFile);
  cmd->add_option("--every", args->every,
                  "write every Nth frame (default: every frame; with --realtime: none)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--realtime", args->realtime,
                "replay at --rate through tracking (mapping thread) while a render thread draws "
                "the newest frame: render time and camera-to-display latency");
  cmd->add_option("--rate", args->rate, "replay rate for --realtime (1 = real time)")
      ->check(CLI::Range(0.05, 100.0))
      ->capture_default_str();
  cmd->add_option("--board", args->board, "board file: display size and tracker capacities")
      ->check(CLI::ExistingFile);
  cmd->add_option("--width", args->width_px, "display width in pixels (default: the board's)")
      ->check(CLI::Range(64, 8192));
  cmd->add_option("--height", args->height_px, "display height in pixels")
      ->check(CLI::Range(64, 8192));
  cmd->add_option("--lens", args->lens, "lens pre-distortion k1 k2 (default: off)")->expected(2);
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->callback([args, &run] { run = [args] { return run_render(*args); }; });
}

}  // namespace wallar::cli
