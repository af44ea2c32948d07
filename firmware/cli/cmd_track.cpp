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
#include "wallar/core/error.hpp"
#include "wallar/drivers/cloud/cloud_io.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/tum_trajectory.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/eval/trajectory.hpp"
#include "wallar/dsp/imu/static_init.hpp"
#include "wallar/eval/output.hpp"
#include "wallar/firmware/tracking.hpp"

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
  int max_tracks = 300;
};

std::int64_t clock_ns() { return monotonic_now_ns(); }

struct Sink final : source::SensorSink {
  firmware::TrackingSystem& system;
  std::vector<dsp::TrackResult> results;
  explicit Sink(firmware::TrackingSystem& s) : system(s) {}
  void on_imu(const ImuSample& sample) override { system.on_imu(sample); }
  void on_stereo(const StereoFrame& frame) override { results.push_back(system.on_stereo(frame)); }
};

struct Percentiles {
  double mean_ms = 0, p50_ms = 0, p99_ms = 0, max_ms = 0;
};
Percentiles percentiles(std::vector<std::int64_t> v) {
  Percentiles p;
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  double sum = 0;
  for (std::int64_t x : v) sum += static_cast<double>(x);
  const auto at = [&](double q) {
    return static_cast<double>(v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))]) * 1e-6;
  };
  p.mean_ms = sum / static_cast<double>(v.size()) * 1e-6;
  p.p50_ms = at(0.5);
  p.p99_ms = at(0.99);
  p.max_ms = static_cast<double>(v.back()) * 1e-6;
  return p;
}
nlohmann::json to_json(const Percentiles& p) {
  return {{"mean_ms", p.mean_ms}, {"p50_ms", p.p50_ms}, {"p99_ms", p.p99_ms}, {"max_ms", p.max_ms}};
}

/// Rotation taking the body's measured "up" to +z (the yaw left as it is).
Eigen::Matrix3d gravity_alignment(const recording::EurocRecording& rec, TimeNs t0_ns) {
  const auto still = dsp::estimate_static_imu(rec.imu, t0_ns - kNsPerS / 2, t0_ns + kNsPerS / 2);
  if (!still) {
    throw InputError(rec.mav0.string() +
                     ": --gravity-aligned needs IMU samples around the first frame");
  }
  return still->q_world_body.toRotationMatrix();
}

int run_track(const TrackArgs& a) {
  const recording::EurocRecording rec = recording::read_euroc(a.recording);
  if (rec.cams[0].frames.empty()) throw InputError(a.recording + ": the recording has no frames");
  firmware::TrackingOptions options;
  options.mapping_thread = !a.lockstep;
  options.use_gyro = !a.no_gyro && !rec.imu.empty();
  options.tracker.max_tracks = a.max_tracks;
  std::unique_ptr<firmware::TrackingSystem> system;
  try {
    system = std::make_unique<firmware::TrackingSystem>(rec.rig(), options, &clock_ns);
  } catch (const std::invalid_argument& e) {
    throw InputError(a.recording + ": calibration: " + e.what());
  }
  Sink sink(*system);
  source::ReplayOptions replay;
  replay.rate = 0.0;
  source::ReplaySource(rec, replay).run(sink, stop_requested());
  const std::shared_ptr<const dsp::MapSnapshot> map = system->finish();
  if (sink.results.empty()) throw InputError(a.recording + ": no stereo pair could be formed");

  // Output frame: world = the first body pose (optionally turned so z is up).
  const SE3d T_body_rect = system->tracker().T_body_rect();
  SE3d R_align = SE3d::Identity();  // first body pose -> output world
  if (a.gravity_aligned) R_align.linear() = gravity_alignment(rec, sink.results.front().t_ns);
  // Tracker world (the first rectified left camera) -> output world.
  const SE3d T_out_world = R_align * T_body_rect;
  std::vector<StampedPose> poses;
  poses.reserve(sink.results.size());
  for (const dsp::TrackResult& r : sink.results) {
    poses.push_back(StampedPose{r.t_ns, T_out_world * r.T_world_cam * T_body_rect.inverse()});
  }
  if (!a.out.empty()) eval::write_file_atomically(a.out, recording::format_tum(poses));

  PointCloud cloud;
  std::vector<float> sigma;
  if (map) {
    for (std::size_t i = 0; i < map->points.size(); ++i) {
      cloud.push_back((T_out_world * map->points.point(i).cast<double>()).cast<float>());
    }
    cloud.observations = map->points.observations;
    sigma = map->sigma_m;
  }
  if (!a.map.empty()) cloud::write_ply_map(a.map, cloud, sigma);

  // Statistics.
  const firmware::TrackingCounters c = system->counters();
  std::vector<std::int64_t> total, rectify, pyramid, stage1, stage2, keyframe;
  int tracking = 0;
  for (const dsp::TrackResult& r : sink.results) {
    tracking += r.state == dsp::TrackingState::kTracking ? 1 : 0;
    total.push_back(r.times.total_ns);
    rectify.push_back(r.times.rectify_ns);
    pyramid.push_back(r.times.pyramid_ns);
    stage1.push_back(r.times.stage1_ns);
    stage2.push_back(r.times.stage2_ns);
    keyframe.push_back(r.times.keyframe_ns);
  }
  nlohmann::json j = {
      {"recording", a.recording},
      {"frames", sink.results.size()},
      {"tracking_frames", tracking},
      {"lost_frames", c.lost_frames},
      {"relocalisations", c.relocalisations},
      {"keyframes", c.keyframes},
      {"keyframes_dropped", c.keyframes_dropped},
      {"map_points", cloud.size()},
      {"local_adjustments", c.local_adjustments},
      {"global_adjustments", c.global_adjustments},
      {"culled_points", c.culled_points},
      {"mapping", a.lockstep ? "lockstep" : "thread"},
      {"gyro", options.use_gyro},
      {"frame_time", to_json(percentiles(total))},
      {"stage_time",
       {{"rectify", to_json(percentiles(rectify))},
        {"pyramid", to_json(percentiles(pyramid))},
        {"stage1_track", to_json(percentiles(stage1))},
        {"stage2_refind", to_json(percentiles(stage2))},
        {"keyframe", to_json(percentiles(keyframe))}}},
      {"mapping_time_per_keyframe", to_json(percentiles(system->mapping_times_ns()))}};
  const dsp::TrackResult& last = sink.results.back();
  j["final_state"] = dsp::to_string(last.state);

  if (a.eval) {
    if (rec.ground_truth.empty()) throw InputError(a.recording + ": --eval needs ground truth");
    // Ground truth in the same world: the first tracked frame's body pose, turned by the same
    // gravity alignment.
    const auto gt0 = recording::ground_truth_at(rec.ground_truth, poses.front().t_ns);
    if (!gt0) throw InputError(a.recording + ": no ground truth at the first frame");
    std::vector<StampedPose> gt;
    gt.reserve(rec.ground_truth.size());
    for (const recording::GroundTruthState& g : rec.ground_truth) {
      gt.push_back(StampedPose{g.t_ns, R_align * gt0->T_world_body.inverse() * g.T_world_body});
    }
    dsp::TrajectoryEvalOptions eo;
    const double span_s = ns_to_s(poses.back().t_ns - poses.front().t_ns);
    eo.rpe_delta_s = std::min(1.0, std::max(span_s / 2.0, 0.05));
    if (poses.size() >= 3) {
      const dsp::TrajectoryErrors e = dsp::evaluate_trajectory(poses, gt, eo);
      j["ate_rmse_m"] = e.ate_rmse_m;
      j["ate_max_m"] = e.ate_max_m;
      j["rpe_trans_rmse_m"] = e.rpe_trans_rmse_m;
      j["rpe_rot_rmse_deg"] = e.rpe_rot_rmse_deg;
      j["rpe_delta_s"] = e.rpe_delta_s;
      j["path_length_m"] = e.path_length_m;
      j["ate_percent_of_path"] = e.path_length_m > 0 ? 100.0 * e.ate_rmse_m / e.path_length_m : 0.0;
    }
    // Drift: the last pose relative to the first, against the ground truth's (no alignment).
    const auto gt_last = recording::ground_truth_at(rec.ground_truth, poses.back().t_ns);
    if (gt_last) {
      const SE3d gt_rel = gt0->T_world_body.inverse() * gt_last->T_world_body;
      const SE3d est_rel = poses.front().T_world_body.inverse() * poses.back().T_world_body;
      const SE3d err = gt_rel.inverse() * est_rel;
      j["drift_m"] = err.translation().norm();
      j["drift_deg"] = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
    }
  }

  if (a.json) {
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("wallar track: %zu frames, %d tracking, %llu lost; %llu key-frames, %zu map points\n",
                sink.results.size(), tracking, static_cast<unsigned long long>(c.lost_frames),
                static_cast<unsigned long long>(c.keyframes), cloud.size());
    const Percentiles p = percentiles(total);
    std::printf("  frame time: mean %.2f ms, p50 %.2f, p99 %.2f, max %.2f\n", p.mean_ms, p.p50_ms,
                p.p99_ms, p.max_ms);
    if (j.contains("ate_rmse_m")) {
      std::printf("  ATE %.4f m RMS (%.2f %% of %.3f m path), RPE %.4f m / %.3f deg over %.2f s\n",
                  j["ate_rmse_m"].get<double>(), j["ate_percent_of_path"].get<double>(),
                  j["path_length_m"].get<double>(), j["rpe_trans_rmse_m"].get<double>(),
                  j["rpe_rot_rmse_deg"].get<double>(), j["rpe_delta_s"].get<double>());
    }
    if (j.contains("drift_m")) {
      std::printf("  drift (last vs first pose): %.4f m, %.3f deg\n", j["drift_m"].get<double>(),
                  j["drift_deg"].get<double>());
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
  cmd->add_option("--max-tracks", args->max_tracks, "features tracked per frame")
      ->check(CLI::Range(8, 5000));
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->callback([args, &run] { run = [args] { return run_track(*args); }; });
}

}  // namespace wallar::cli
