// SPDX-License-Identifier: Apache-2.0
/// @file offline.cpp
/// @brief A recording through the appliance -> the report in the files' world -> errors, floor.
#include "wallar/firmware/offline.hpp"

#include <algorithm>
#include <cmath>

#include "wallar/core/error.hpp"
#include "wallar/dsp/imu/static_init.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/dsp/walls/room_check.hpp"
#include "wallar/firmware/foxglove_messages.hpp"
#include "wallar/firmware/world_frames.hpp"

namespace wallar::firmware {
namespace {

constexpr double kFloorThresholdM = 0.05;

/// The floor of the map (2-D search with IMU gravity), its inliers fitted freely in 3-D.
std::optional<FloorAgainstGravity> check_floor_of(const PointCloud& map,
                                                  const Eigen::Vector3d& up_imu,
                                                  const std::optional<Eigen::Vector3d>& up_gt) {
  if (map.size() < 20) return std::nullopt;
  dsp::RoomConfig config;
  config.detector.threshold_m = kFloorThresholdM;
  config.gravity = -up_imu;
  config.max_surfaces = 4;
  dsp::RoomEstimator estimator(map.size());
  const dsp::RoomResult room = estimator.estimate(map, config);
  const auto check = dsp::check_floor(map, room, kFloorThresholdM, up_imu, up_gt);
  if (!check) return std::nullopt;
  return FloorAgainstGravity{check->distance_below_viewer_m, check->inliers,
                             check->free_fit_vs_up_deg, check->free_fit_vs_up2_deg};
}

}  // namespace

ApplianceOptions offline_options(ApplianceMode mode) {
  ApplianceOptions o;
  o.mode = mode;
  o.replay.rate = 0.0;
  o.view = false;
  o.realtime = false;
  o.log = [](const std::string&) {};
  // The end of a replay is noticed within a tick, and the reconstruct thread's sleep bounds
  // the stop: short periods keep an offline run as long as its tracking.
  o.supervisor_period_ns = 10 * kNsPerMs;
  o.reconstruct_period_ns = 50 * kNsPerMs;
  return o;
}

RunOutputs outputs_in(const ApplianceReport& report, const SE3d& T_world_tracker) {
  RunOutputs out;
  out.T_world_tracker = T_world_tracker;
  out.poses.reserve(report.trajectory.size());
  for (const PoseRecord& r : report.trajectory) {
    out.poses.push_back(StampedPose{r.t_ns, T_world_tracker * r.T_world_body});
  }
  if (report.map) {
    out.map = transformed(report.map->points, T_world_tracker);
    out.sigma_m = report.map->sigma_m;
    for (const Eigen::Vector3d& c : report.map->keyframe_centres) {
      out.keyframe_centres.push_back(T_world_tracker * c);
    }
  }
  if (report.room) out.room = transformed(*report.room, T_world_tracker);
  return out;
}

namespace {

// The IMU at rest around t0_ns, its accelerometer corrected by the calibration's bias.
std::optional<dsp::StaticImuEstimate> still_around(const recording::EurocRecording& rec,
                                                   TimeNs t0_ns) {
  if (rec.imu.empty()) return std::nullopt;
  return dsp::estimate_static_imu(rec.imu, t0_ns - kNsPerS / 2, t0_ns + kNsPerS / 2, 20,
                                  rec.imu_calib.accel_bias_m_s2);
}

SE3d alignment_of(const dsp::StaticImuEstimate& still) {
  SE3d R_align = SE3d::Identity();
  R_align.linear() = still.q_world_body.toRotationMatrix();
  return R_align;
}

}  // namespace

std::optional<SE3d> gravity_alignment(const recording::EurocRecording& rec, TimeNs t0_ns) {
  const auto still = still_around(rec, t0_ns);
  if (!still) return std::nullopt;
  return alignment_of(*still);
}

void check_evaluation_inputs(const recording::EurocRecording& rec,
                             const RunEvaluationOptions& options) {
  if (options.ground_truth && rec.ground_truth.empty()) {
    throw InputError(rec.mav0.string() +
                     ": evaluation needs ground truth (state_groundtruth_estimate0)");
  }
}

RunEvaluation evaluate_run(const recording::EurocRecording& rec, const ApplianceReport& report,
                           const RunEvaluationOptions& options) {
  const std::string name = rec.mav0.string();
  check_evaluation_inputs(rec, options);
  const std::vector<PoseRecord>& frames = report.trajectory;
  if (frames.empty()) throw InputError(name + ": no stereo pair could be formed");
  const auto rejected = std::count_if(frames.begin(), frames.end(),
                                      [](const PoseRecord& r) { return r.rejected != nullptr; });
  if (static_cast<std::size_t>(rejected) == frames.size()) {
    throw InputError(name + ": no frame could be tracked: " + frames.front().rejected +
                     " (calibration " + std::to_string(rec.cams[0].calib.width_px) + "x" +
                     std::to_string(rec.cams[0].calib.height_px) + ")");
  }

  // World: the first body pose, optionally turned so z is up.
  const TimeNs t0_ns = frames.front().t_ns;
  const std::optional<dsp::StaticImuEstimate> still = still_around(rec, t0_ns);
  SE3d R_align = SE3d::Identity();
  if (options.gravity_aligned) {
    if (!still) throw InputError(name + ": gravity alignment needs IMU samples around the start");
    R_align = alignment_of(*still);
  }
  RunEvaluation out;
  out.gravity_aligned = options.gravity_aligned;
  out.outputs = outputs_in(report, R_align * report.T_body_rect);
  const std::vector<StampedPose>& poses = out.outputs.poses;

  std::optional<recording::GroundTruthState> gt0;
  if (!rec.ground_truth.empty()) gt0 = recording::ground_truth_at(rec.ground_truth, t0_ns);
  // "Up" in the output world, from the IMU and from the ground truth.
  if (still) {
    const Eigen::Vector3d up_imu = R_align.linear() * still->mean_accel_m_s2.normalized();
    std::optional<Eigen::Vector3d> up_gt;
    if (gt0) up_gt = R_align.linear() * gt0->up_body();
    out.floor = check_floor_of(out.outputs.map, up_imu, up_gt);
  }
  if (options.ground_truth) {
    if (!gt0) throw InputError(name + ": no ground truth at the first frame");
    std::vector<StampedPose> gt;
    gt.reserve(rec.ground_truth.size());
    for (const recording::GroundTruthState& g : rec.ground_truth) {
      gt.push_back(StampedPose{g.t_ns, R_align * gt0->T_world_body.inverse() * g.T_world_body});
    }
    if (poses.size() >= 3) {
      dsp::TrajectoryEvalOptions eo;
      const double span_s = ns_to_s(poses.back().t_ns - poses.front().t_ns);
      eo.rpe_delta_s = std::clamp(span_s / 2.0, 0.05, 1.0);
      try {
        out.errors = dsp::evaluate_trajectory(poses, gt, eo);
      } catch (const std::invalid_argument&) {
        // Too few frames inside the ground truth's span: no ATE, the drift below still holds.
      }
    }
    // Position tracks (a car's GPS/INS) come with identity orientations: relative poses of the
    // truth are then in the world's axes, not the body's, and RPE and drift mean nothing.
    out.ground_truth_positions_only =
        std::all_of(rec.ground_truth.begin(), rec.ground_truth.end(),
                    [](const recording::GroundTruthState& g) {
                      return g.T_world_body.linear() == Eigen::Matrix3d::Identity();
                    }) &&
        rec.ground_truth.size() >= 2 &&
        (rec.ground_truth.front().T_world_body.translation() -
         rec.ground_truth.back().T_world_body.translation())
                .norm() > 0.0;
    if (const auto gt_last = recording::ground_truth_at(rec.ground_truth, poses.back().t_ns);
        gt_last && !out.ground_truth_positions_only) {
      const SE3d gt_rel = gt0->T_world_body.inverse() * gt_last->T_world_body;
      const SE3d est_rel = poses.front().T_world_body.inverse() * poses.back().T_world_body;
      const SE3d err = gt_rel.inverse() * est_rel;
      out.drift_m = err.translation().norm();
      out.drift_deg = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
    }
  }
  return out;
}

void write_outputs_mcap(recording::McapRecordingWriter& w, const RunOutputs& o) {
  auto channel = [&w](const foxglove::Schema& s, const char* topic) {
    return w.add_json_channel(s.name, s.json_schema, topic);
  };
  const std::uint16_t pose = channel(foxglove::pose_in_frame_schema(), "/pose");
  const std::uint16_t tf = channel(foxglove::frame_transform_schema(), "/tf");
  const std::uint16_t map = channel(foxglove::point_cloud_schema(), "/map");
  const std::uint16_t walls = channel(foxglove::scene_update_schema(), "/walls");
  for (const StampedPose& p : o.poses) {
    w.write_json(pose, p.t_ns, foxglove::pose_in_frame(p.t_ns, p.T_world_body));
    w.write_json(tf, p.t_ns, foxglove::frame_transform(p.t_ns, p.T_world_body, "body"));
  }
  const TimeNs t_end = o.poses.empty() ? 0 : o.poses.back().t_ns;
  const std::vector<Wall> none;
  const std::vector<Wall>& surfaces = o.room ? o.room->model.walls : none;
  w.write_json(map, t_end, foxglove::point_cloud(t_end, o.map, o.sigma_m, surfaces));
  w.write_json(walls, t_end, foxglove::scene_update(t_end, surfaces));
}

}  // namespace wallar::firmware
