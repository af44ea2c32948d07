// SPDX-License-Identifier: Apache-2.0
/// @file cmd_track.cpp
/// @brief `wallar track RECORDING`: the stereo tracker and mapper over a recording; the
/// trajectory in TUM format, the sparse map as PLY, and errors against the ground truth.
///
/// Frames: poses are T_world_body of the recording's body frame (EuRoC: the IMU, through
/// T_BS). The world is the first tracked body pose, or with --gravity-aligned that pose turned
/// so z is up (gravity from the IMU's first still second). map.ply is in the same world frame.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.hpp"
#include "percentiles.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/cloud/cloud_io.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/tum_trajectory.hpp"
#include "wallar/eval/output.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/track_recording.hpp"

namespace wallar::cli {
namespace {

struct TrackArgs {
  std::string recording;
  std::string out;
  std::string map;
  bool eval = false;
  bool gravity_aligned = false;
  bool lockstep = false;
  bool no_gyro = false;
  bool json = false;
  std::string board;
};

int run_track(const TrackArgs& a) {
  const recording::EurocRecording rec = recording::read_euroc(a.recording);
  firmware::TrackRecordingOptions options;
  // Capacities from the board file when given (as the firmware sizes them at start-up).
  options.tracking = firmware::tracking_options(
      a.board.empty() ? firmware::TrackingConfig{} : firmware::load_board(a.board).tracking);
  if (a.lockstep) options.tracking.mapping_thread = false;
  options.tracking.use_gyro = !a.no_gyro;
  options.gravity_aligned = a.gravity_aligned;
  options.evaluate = a.eval;
  const firmware::TrackRecordingResult r =
      firmware::track_recording(rec, options, stop_requested());
  if (!a.out.empty()) eval::write_file_atomically(a.out, recording::format_tum(r.poses));
  if (!a.map.empty()) cloud::write_ply_map(a.map, r.map, r.sigma_m);

  const firmware::TrackingCounters& c = r.counters;
  std::vector<std::int64_t> total, rectify, pyramid, stage1, stage2, keyframe;
  int tracking = 0;
  for (const dsp::TrackResult& f : r.frames) {
    tracking += f.state == dsp::TrackingState::kTracking ? 1 : 0;
    total.push_back(f.times.total_ns);
    rectify.push_back(f.times.rectify_ns);
    pyramid.push_back(f.times.pyramid_ns);
    stage1.push_back(f.times.stage1_ns);
    stage2.push_back(f.times.stage2_ns);
    keyframe.push_back(f.times.keyframe_ns);
  }
  nlohmann::json j = {
      {"recording", a.recording},
      {"frames", r.frames.size()},
      {"tracking_frames", tracking},
      {"lost_frames", c.lost_frames},
      {"rejected_frames", c.rejected_frames},
      {"relocalisations", c.relocalisations},
      {"keyframes", c.keyframes},
      {"keyframes_deferred", c.keyframes_deferred},
      {"new_segments", c.new_segments},
      {"map_full_keyframes", c.map_full_keyframes},
      {"culled_keyframes", c.culled_keyframes},
      {"stale_updates", c.stale_updates},
      {"map_points", r.map.size()},
      {"local_adjustments", c.local_adjustments},
      {"global_adjustments", c.global_adjustments},
      {"culled_points", c.culled_points},
      {"mapping", options.tracking.mapping_thread ? "thread" : "lockstep"},
      {"final_state", dsp::to_string(r.frames.back().state)},
      {"frame_time", to_json(percentiles(total))},
      {"stage_time",
       {{"rectify", to_json(percentiles(rectify))},
        {"pyramid", to_json(percentiles(pyramid))},
        {"stage1_track", to_json(percentiles(stage1))},
        {"stage2_refind", to_json(percentiles(stage2))},
        {"keyframe", to_json(percentiles(keyframe))}}},
      {"mapping_time_per_keyframe", to_json(percentiles(r.mapping_times_ns))}};
  if (r.errors) {
    const dsp::TrajectoryErrors& e = *r.errors;
    j["ate_rmse_m"] = e.ate_rmse_m;
    j["ate_max_m"] = e.ate_max_m;
    j["rpe_trans_rmse_m"] = e.rpe_trans_rmse_m;
    j["rpe_rot_rmse_deg"] = e.rpe_rot_rmse_deg;
    j["rpe_delta_s"] = e.rpe_delta_s;
    j["path_length_m"] = e.path_length_m;
  }
  if (r.drift_m) {
    j["drift_m"] = *r.drift_m;
    j["drift_deg"] = *r.drift_deg;
  }
  if (r.floor) {
    j["floor"] = {{"distance_below_m", r.floor->distance_below_m},
                  {"inliers", r.floor->inliers},
                  {"free_fit_vs_imu_gravity_deg", r.floor->free_fit_vs_imu_deg}};
    if (r.floor->free_fit_vs_ground_truth_deg) {
      j["floor"]["free_fit_vs_ground_truth_gravity_deg"] = *r.floor->free_fit_vs_ground_truth_deg;
    }
  }

  if (a.json) {
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("wallar track: %zu frames, %d tracking, %llu lost, %llu rejected; %llu key-frames, "
                "%zu map points\n",
                r.frames.size(), tracking, static_cast<unsigned long long>(c.lost_frames),
                static_cast<unsigned long long>(c.rejected_frames),
                static_cast<unsigned long long>(c.keyframes), r.map.size());
    const Percentiles p = percentiles(total);
    std::printf("  frame time: mean %.2f ms, p50 %.2f, p99 %.2f, max %.2f\n", p.mean_ms, p.p50_ms,
                p.p99_ms, p.max_ms);
    if (r.errors) {
      const dsp::TrajectoryErrors& e = *r.errors;
      std::printf("  ATE %.4f m RMS over a %.3f m path, RPE %.4f m / %.3f deg per %.2f s\n",
                  e.ate_rmse_m, e.path_length_m, e.rpe_trans_rmse_m, e.rpe_rot_rmse_deg,
                  e.rpe_delta_s);
    }
    if (r.drift_m) {
      std::printf("  drift (last pose vs first, against ground truth): %.4f m, %.3f deg\n",
                  *r.drift_m, *r.drift_deg);
    }
    if (r.floor) {
      std::printf("  floor %.3f m below, %zu points; their free fit is %.2f deg from IMU gravity",
                  r.floor->distance_below_m, r.floor->inliers, r.floor->free_fit_vs_imu_deg);
      if (r.floor->free_fit_vs_ground_truth_deg) {
        std::printf(", %.2f deg from ground-truth gravity", *r.floor->free_fit_vs_ground_truth_deg);
      }
      std::printf("\n");
    }
    if (!a.out.empty()) std::printf("  wrote %s\n", a.out.c_str());
    if (!a.map.empty()) std::printf("  wrote %s\n", a.map.c_str());
  }
  return stop_requested().load() ? kExitInterrupted : kExitOk;
}

}  // namespace

void add_track_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<TrackArgs>();
  CLI::App* cmd = app.add_subcommand(
      "track", "Track the stereo camera through a recording and map it (TUM trajectory, PLY map)");
  cmd->add_option("recording", args->recording, "EuRoC-layout recording (ROOT or ROOT/mav0)")
      ->required();
  cmd->add_option("--out", args->out,
                  "trajectory file, TUM format: t x y z qx qy qz qw (t in s), T_world_body");
  cmd->add_option("--map", args->map, "sparse map as PLY (x y z sigma observations), world frame");
  cmd->add_flag("--eval", args->eval, "compare with the recording's ground truth (ATE, RPE, drift)");
  cmd->add_flag("--gravity-aligned", args->gravity_aligned,
                "turn the world so z is up (gravity from the IMU's first second)");
  cmd->add_flag("--lockstep", args->lockstep,
                "map on the tracking thread after each key-frame (repeatable results)");
  cmd->add_flag("--no-gyro", args->no_gyro, "do not use the gyro to predict rotation");
  cmd->add_option("--board", args->board,
                  "board file whose tracking: section sizes the tracker (default: built-in sizes)");
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->callback([args, &run] { run = [args] { return run_track(*args); }; });
}

}  // namespace wallar::cli
