// SPDX-License-Identifier: Apache-2.0
/// @file cmd_track.cpp
/// @brief `wallar track RECORDING`: the appliance's modules over a recording (replay, tracking
/// with the attitude filter and degraded modes, mapping, reconstruction), as fast as tracking
/// goes; the trajectory in TUM format, the sparse map as PLY, the walls as JSON, and errors
/// against the ground truth.
///
/// Modes: every frame tracked with mapping on its thread (default), or --lockstep (mapping on
/// the tracking thread after each key-frame, walls at fixed points: repeatable; the same
/// trajectory as `wallar run --deterministic`).
///
/// Frames: poses are T_world_body of the recording's body frame (EuRoC: the IMU, through
/// T_BS), one per frame tracking took (tracked, lost or rejected: the pose held). The world is
/// the first body pose, or with --gravity-aligned that pose turned so z is up (gravity from
/// the IMU's first still second). map.ply and walls.json are in the same world frame.
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
#include "wallar/firmware/offline.hpp"
#include "wallar/firmware/report.hpp"

namespace wallar::cli {
namespace {

struct TrackArgs {
  std::string recording;
  std::string out;
  std::string map;
  std::string walls;
  std::string mcap;
  bool eval = false;
  bool gravity_aligned = false;
  bool lockstep = false;
  bool no_gyro = false;
  bool json = false;
  std::string board;
};

// The recording's streams and the run's outputs in one MCAP file, for Foxglove: /pose and /tf
// (world -> body) per frame, the final map (/map) and surfaces (/walls) at the last frame.
void write_run_mcap(const std::string& path, const recording::EurocRecording& rec,
                    const firmware::RunOutputs& o) {
  recording::McapRecordingWriter w(path, rec.rig(), {}, !rec.ground_truth.empty());
  recording::write_streams(rec, w);
  firmware::write_outputs_mcap(w, o);
  w.close();
}

int run_track(const TrackArgs& a) {
  const recording::EurocRecording rec = read_recording_reporting(a.recording);
  // Capacities from the board file when given (as the firmware sizes them at start-up).
  const firmware::BoardConfig board =
      a.board.empty() ? firmware::BoardConfig{} : firmware::load_board(a.board);
  firmware::RunEvaluationOptions eval_options;
  eval_options.gravity_aligned = a.gravity_aligned;
  eval_options.ground_truth = a.eval;
  firmware::check_evaluation_inputs(rec, eval_options);
  if (a.gravity_aligned && rec.imu.empty()) {
    throw InputError(rec.mav0.string() + ": --gravity-aligned needs an IMU (imu0 has no samples)");
  }
  firmware::ApplianceOptions options = firmware::offline_options(
      a.lockstep ? firmware::ApplianceMode::kLockStep : firmware::ApplianceMode::kEveryFrame);
  options.use_gyro = !a.no_gyro;
  const firmware::ApplianceReport report =
      firmware::run_over_recording(rec, board, options, stop_requested());
  const firmware::RunEvaluation r = firmware::evaluate_run(rec, report, eval_options);
  const firmware::RunOutputs& o = r.outputs;
  const char* world = a.gravity_aligned ? "world: the first body pose turned so z is up"
                                        : "world: the first body pose";
  if (!a.out.empty()) eval::write_file_atomically(a.out, recording::format_tum(o.poses));
  if (!a.map.empty()) cloud::write_ply_map(a.map, o.map, o.sigma_m);
  if (!a.mcap.empty()) write_run_mcap(a.mcap, rec, o);
  if (!a.walls.empty()) {
    nlohmann::json walls = firmware::to_json(o.room ? *o.room : dsp::RoomResult{});
    walls["mode"] = firmware::to_string(report.room_gravity);
    walls["frame"] = world;
    eval::write_file_atomically(a.walls, walls.dump(2) + "\n");
  }

  const firmware::TrackingCounters& c = report.tracking;
  std::vector<std::int64_t> total, rectify, pyramid, stage1, stage2, keyframe;
  int tracking = 0;
  for (const firmware::PoseRecord& f : report.trajectory) {
    tracking += f.state == dsp::TrackingState::kTracking && f.rejected == nullptr ? 1 : 0;
    total.push_back(f.times.total_ns);
    rectify.push_back(f.times.rectify_ns);
    pyramid.push_back(f.times.pyramid_ns);
    stage1.push_back(f.times.stage1_ns);
    stage2.push_back(f.times.stage2_ns);
    keyframe.push_back(f.times.keyframe_ns);
  }
  const firmware::DegradedCounters& d = report.degraded;
  nlohmann::json j = {{"recording", a.recording},
                      {"mode", firmware::to_string(report.mode)},
                      {"imu", report.imu},
                      {"frames", report.trajectory.size()},
                      {"tracking_frames", tracking},
                      {"lost_frames", c.lost_frames},
                      {"rejected_frames", c.rejected_frames},
                      {"relocalisations", c.relocalisations},
                      {"keyframes", c.keyframes},
                      {"keyframes_deferred", c.keyframes_deferred},
                      {"new_segments", c.new_segments},
                      {"map_full_keyframes", c.map_full_keyframes},
                      {"culled_keyframes", c.culled_keyframes},
                      {"map_keyframes", c.map_keyframes},
                      {"stale_updates", c.stale_updates},
                      {"map_points", o.map.size()},
                      {"local_adjustments", c.local_adjustments},
                      {"global_adjustments", c.global_adjustments},
                      {"culled_points", c.culled_points},
                      {"mapping", options.mode == firmware::ApplianceMode::kLockStep ||
                                          !board.tracking.mapping_thread
                                      ? "lockstep"
                                      : "thread"},
                      {"final_state", dsp::to_string(report.trajectory.back().state)},
                      {"surfaces", o.room ? o.room->model.walls.size() : 0},
                      {"reconstructions", report.reconstructions},
                      {"degraded",
                       {{"camera_lost", d.camera_lost},
                        {"camera_recovered", d.camera_recovered},
                        {"imu_lost", d.imu_lost},
                        {"imu_recovered", d.imu_recovered},
                        {"imu_only_poses", d.imu_only_poses}}},
                      {"events", report.events},
                      {"frame_time", to_json(percentiles(total))},
                      {"stage_time",
                       {{"rectify", to_json(percentiles(rectify))},
                        {"pyramid", to_json(percentiles(pyramid))},
                        {"stage1_track", to_json(percentiles(stage1))},
                        {"stage2_refind", to_json(percentiles(stage2))},
                        {"keyframe", to_json(percentiles(keyframe))}}},
                      {"mapping_time_per_keyframe", to_json(percentiles(report.mapping_times_ns))}};
  if (r.errors) {
    const dsp::TrajectoryErrors& e = *r.errors;
    j["ate_rmse_m"] = e.ate_rmse_m;
    j["ate_max_m"] = e.ate_max_m;
    if (!r.ground_truth_positions_only) {
      j["rpe_trans_rmse_m"] = e.rpe_trans_rmse_m;
      j["rpe_rot_rmse_deg"] = e.rpe_rot_rmse_deg;
      j["rpe_delta_s"] = e.rpe_delta_s;
    }
    j["path_length_m"] = e.path_length_m;
    j["ground_truth"] = r.ground_truth_positions_only ? "positions only" : "poses";
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
    std::printf(
        "wallar track: %zu frames, %d tracking, %llu lost, %llu rejected; %llu key-frames, "
        "%zu map points, %zu surfaces (%s%s)\n",
        report.trajectory.size(), tracking, static_cast<unsigned long long>(c.lost_frames),
        static_cast<unsigned long long>(c.rejected_frames),
        static_cast<unsigned long long>(c.keyframes), o.map.size(),
        o.room ? o.room->model.walls.size() : std::size_t{0}, firmware::to_string(report.mode),
        report.imu ? "" : ", vision only: no IMU");
    for (const std::string& e : report.events) std::printf("  event: %s\n", e.c_str());
    const Percentiles p = percentiles(total);
    std::printf("  frame time: mean %.2f ms, p50 %.2f, p99 %.2f, max %.2f\n", p.mean_ms, p.p50_ms,
                p.p99_ms, p.max_ms);
    if (r.errors) {
      const dsp::TrajectoryErrors& e = *r.errors;
      if (r.ground_truth_positions_only) {
        std::printf(
            "  ATE %.4f m RMS over a %.3f m path (the ground truth has positions only: no RPE or "
            "drift)\n",
            e.ate_rmse_m, e.path_length_m);
      } else {
        std::printf("  ATE %.4f m RMS over a %.3f m path, RPE %.4f m / %.3f deg per %.2f s\n",
                    e.ate_rmse_m, e.path_length_m, e.rpe_trans_rmse_m, e.rpe_rot_rmse_deg,
                    e.rpe_delta_s);
      }
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
    for (const std::string* f : {&a.out, &a.map, &a.walls}) {
      if (!f->empty()) std::printf("  wrote %s\n", f->c_str());
    }
  }
  return stop_requested().load() ? kExitInterrupted : kExitOk;
}

}  // namespace

void add_track_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<TrackArgs>();
  CLI::App* cmd = app.add_subcommand(
      "track",
      "Run the appliance's tracking, mapping and reconstruction over a recording (TUM trajectory, "
      "PLY map, walls JSON)");
  cmd->add_option("recording", args->recording,
                  "Recording: EuRoC folder (ROOT or ROOT/mav0) or .mcap file")
      ->required();
  cmd->add_option("--out", args->out,
                  "trajectory file, TUM format: t x y z qx qy qz qw (t in s), T_world_body");
  cmd->add_option("--map", args->map, "sparse map as PLY (x y z sigma observations), world frame");
  cmd->add_option("--walls", args->walls,
                  "the reconstruction's final surfaces (wallar walls JSON schema), world frame");
  cmd->add_option("--mcap", args->mcap,
                  "the recording and the run in one MCAP file for Foxglove: its streams, /pose, "
                  "/tf, the final /map (foxglove.PointCloud) and /walls (foxglove.SceneUpdate)");
  cmd->add_flag("--eval", args->eval,
                "compare with the recording's ground truth (ATE, RPE, drift)");
  cmd->add_flag("--gravity-aligned", args->gravity_aligned,
                "turn the world so z is up (gravity from the IMU's first second)");
  cmd->add_flag("--lockstep", args->lockstep,
                "map on the tracking thread after each key-frame, walls at fixed points "
                "(repeatable: the trajectory of wallar run --deterministic)");
  cmd->add_flag("--no-gyro", args->no_gyro, "do not use the gyro to predict rotation");
  cmd->add_option("--board", args->board,
                  "board file whose tracking: section sizes the tracker (default: built-in sizes)");
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->callback([args, &run] { run = [args] { return run_track(*args); }; });
}

}  // namespace wallar::cli
