// SPDX-License-Identifier: Apache-2.0
/// @file cmd_render.cpp
/// @brief `wallar render RECORDING --out DIR [--walls walls.json]`: the headset view of a
/// recording, offline. The appliance's modules track it in lock step (as `wallar track
/// --lockstep`) and reconstruct its walls (unless --walls gives them); then every frame is
/// drawn with its pose, every Nth written as PNG.
///
/// --realtime runs the appliance at --rate with its render thread on: the view draws the
/// newest frame tracking posted and the reconstruction's newest walls (or the given ones), and
/// the command reports tracking time, render time and camera-to-display latency.
///
/// Frames: the world is the first body pose turned so z is up (`wallar track
/// --gravity-aligned`), or without an IMU the first body pose; a walls.json given with --walls
/// must be in that frame (the one this command writes is).
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "percentiles.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/headset_view.hpp"
#include "wallar/firmware/offline.hpp"
#include "wallar/firmware/report.hpp"
#include "wallar/firmware/world_frames.hpp"

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
    out[c]->image = recording::load_frame_gray(rec, static_cast<int>(c), *it);
  }
  return f;
}

/// The appliance at `rate` with its render thread drawing the newest frame tracking posted:
/// the end-to-end latency. `walls` (in the world of the files, `T_world_body0` from the first
/// body pose's) replace the reconstruction's when given.
int run_realtime(const RenderArgs& a, const recording::EurocRecording& rec,
                 const firmware::BoardConfig& board, const std::optional<WallModel>& walls,
                 const SE3d& T_world_body0) {
  firmware::ApplianceOptions options =
      firmware::offline_options(firmware::ApplianceMode::kRealTime);
  options.replay.rate = a.rate;
  options.view = true;
  if (a.every > 0) {
    options.png_dir = a.out;
    options.png_every = a.every;
  }
  if (walls) options.view_walls = firmware::transformed(*walls, T_world_body0.inverse());
  const firmware::ApplianceReport report =
      firmware::run_over_recording(rec, board, options, stop_requested());
  const firmware::LiveViewStats& s = report.view;
  std::vector<std::int64_t> track_ns;
  for (const firmware::PoseRecord& r : report.trajectory) track_ns.push_back(r.times.total_ns);
  const Percentiles render = percentiles(s.view.render_ns);
  const Percentiles latency = percentiles(s.view.latency_ns);
  const Percentiles track = percentiles(track_ns);
  const std::size_t surfaces = walls         ? walls->walls.size()
                               : report.room ? report.room->model.walls.size()
                                             : 0;
  nlohmann::json summary = {{"recording", a.recording},
                            {"mode", "realtime"},
                            {"rate", a.rate},
                            {"display", s.display},
                            {"frames_in", report.frames_in},
                            {"frames_overwritten", report.frames_overwritten},
                            {"posted", s.posted},
                            {"drawn", s.view.frames},
                            {"skipped", s.skipped},
                            {"present_failures", s.view.present_failures},
                            {"written", s.view.written},
                            {"walls", surfaces},
                            {"walls_source", walls ? "given" : "reconstruction"},
                            {"tracking_time", to_json(track)},
                            {"render_time", to_json(render)},
                            {"camera_to_display_latency", to_json(latency)},
                            {"replay", firmware::to_json(report.replay)}};
  std::ofstream(fs::path(a.out) / "render_summary.json") << summary.dump(2) << "\n";
  if (a.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::printf(
        "wallar render --realtime: %llu of %llu frames tracked and posted at %.2gx (%llu "
        "overwritten), %llu drawn on %s, %llu skipped (newer frame waiting)\n",
        static_cast<unsigned long long>(s.posted),
        static_cast<unsigned long long>(report.frames_in), a.rate,
        static_cast<unsigned long long>(report.frames_overwritten),
        static_cast<unsigned long long>(s.view.frames), s.display.c_str(),
        static_cast<unsigned long long>(s.skipped));
    std::printf("  tracking per frame: p50 %.2f ms, p99 %.2f; render: p50 %.2f ms, p99 %.2f\n",
                track.p50_ms, track.p99_ms, render.p50_ms, render.p99_ms);
    std::printf("  camera-to-display latency: p50 %.2f ms, p99 %.2f, max %.2f\n", latency.p50_ms,
                latency.p99_ms, latency.max_ms);
  }
  return report.interrupted || stop_requested().load() ? kExitInterrupted : kExitOk;
}

int run_render(const RenderArgs& a) {
  const recording::EurocRecording rec = read_recording_reporting(a.recording);
  firmware::BoardConfig board =
      a.board.empty() ? firmware::BoardConfig{} : firmware::load_board(a.board);
  board.display.backend = "headless";  // offline: never the panel
  if (a.width_px > 0) board.display.width_px = a.width_px;
  if (a.height_px > 0) board.display.height_px = a.height_px;
  if (a.lens.size() == 2) {
    board.display.lens_k1 = a.lens[0];
    board.display.lens_k2 = a.lens[1];
  }
  std::optional<WallModel> given;
  if (!a.walls.empty()) given = firmware::read_walls_json(a.walls);
  std::error_code ec;
  fs::create_directories(a.out, ec);
  if (ec) throw_input_error(a.out, 0, "cannot create output folder: " + ec.message());
  if (a.realtime) {
    // The world of the walls: gravity's when the IMU is still around the first frame.
    SE3d T_world_body0 = SE3d::Identity();
    if (given && !rec.cams[0].frames.empty()) {
      T_world_body0 = firmware::gravity_alignment(rec, rec.cams[0].frames.front().t_ns)
                          .value_or(SE3d::Identity());
    }
    return run_realtime(a, rec, board, given, T_world_body0);
  }

  // The whole recording through the appliance in lock step (repeatable), as `wallar track`.
  const firmware::ApplianceReport report = firmware::run_over_recording(
      rec, board, firmware::offline_options(firmware::ApplianceMode::kLockStep), stop_requested());
  firmware::RunEvaluationOptions eval_options;
  eval_options.gravity_aligned = !rec.imu.empty();
  const firmware::RunEvaluation track = firmware::evaluate_run(rec, report, eval_options);

  // The walls: given, or the appliance's reconstruction, in the same world.
  WallModel walls;
  if (given) {
    walls = *given;
  } else {
    const dsp::RoomResult room = track.outputs.room.value_or(dsp::RoomResult{});
    walls = room.model;
    nlohmann::json walls_json = firmware::to_json(room);
    walls_json["mode"] = firmware::to_string(report.room_gravity);
    walls_json["frame"] = track.gravity_aligned
                              ? "world: the first body pose turned so z is up (wallar track "
                                "--gravity-aligned)"
                              : "world: the first body pose (no IMU)";
    std::ofstream(fs::path(a.out) / "walls.json") << walls_json.dump(2) << "\n";
  }

  firmware::HeadsetViewOptions view_options = firmware::view_options(board.display);
  view_options.png_dir = a.out;
  view_options.png_every = std::max(1, a.every);
  const RigCalibration rig = rec.rig();
  firmware::HeadsetView view(rig, view_options);
  const double fps = rig.cams[0].rate_hz;
  for (std::size_t i = 0; i < report.trajectory.size() && !stop_requested().load(); ++i) {
    const firmware::PoseRecord& r = report.trajectory[i];
    const StereoFrame pair = load_pair(rec, r.t_ns, i);
    display::HudState hud;
    hud.tracking = dsp::to_string(r.state);
    hud.fps = fps;
    hud.walls = static_cast<int>(walls.walls.size());
    const bool pose_valid = r.state == dsp::TrackingState::kTracking;
    if (!view.show(pair, 0, track.outputs.poses[i].T_world_body, pose_valid, &walls, hud)) {
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
  cmd->add_option("recording", args->recording,
                  "Recording: EuRoC folder (ROOT or ROOT/mav0) or .mcap file")
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
                "run the appliance at --rate with its render thread drawing the newest frame: "
                "render time and camera-to-display latency");
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
