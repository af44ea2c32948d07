// SPDX-License-Identifier: Apache-2.0
/// @file track_recording.cpp
/// @brief Replay -> TrackingAndMapping -> poses and map in the body's world -> errors and floor.
#include "wallar/firmware/track_recording.hpp"

#include <cmath>

#include "wallar/core/error.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/imu/static_init.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/dsp/walls/room_check.hpp"

namespace wallar::firmware {
namespace {

constexpr double kFloorThresholdM = 0.05;

std::int64_t clock_ns() { return monotonic_now_ns(); }

struct Sink final : source::SensorSink {
  explicit Sink(TrackingAndMapping& s) : system(s) {}
  void on_imu(const ImuSample& sample) override { system.on_imu(sample); }
  void on_stereo(const StereoFrame& frame) override { frames.push_back(system.on_stereo(frame)); }
  TrackingAndMapping& system;
  std::vector<dsp::TrackResult> frames;
};

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

TrackRecordingResult track_recording(const recording::EurocRecording& rec,
                                     const TrackRecordingOptions& options,
                                     const std::atomic<bool>& stop) {
  const std::string name = rec.mav0.string();
  if (rec.cams[0].frames.empty() || rec.cams[1].frames.empty()) {
    throw InputError(name + ": the recording has no stereo frames");
  }
  if (options.evaluate && rec.ground_truth.empty()) {
    throw InputError(name + ": evaluation needs ground truth (state_groundtruth_estimate0)");
  }
  TrackingOptions tracking = options.tracking;
  tracking.use_gyro = tracking.use_gyro && !rec.imu.empty();
  std::unique_ptr<TrackingAndMapping> system;
  try {
    system = std::make_unique<TrackingAndMapping>(rec.rig(), tracking, &clock_ns);
  } catch (const std::invalid_argument& e) {
    throw InputError(name + ": calibration: " + e.what());
  }
  Sink sink(*system);
  source::ReplayOptions replay;
  replay.rate = 0.0;
  source::ReplaySource(rec, replay).run(sink, stop);
  const std::shared_ptr<const dsp::MapSnapshot> map = system->finish();
  if (sink.frames.empty()) throw InputError(name + ": no stereo pair could be formed");
  if (system->counters().rejected_frames == sink.frames.size()) {
    throw InputError(name + ": no frame could be tracked: " + sink.frames.front().rejected +
                     " (calibration " + std::to_string(rec.cams[0].calib.width_px) + "x" +
                     std::to_string(rec.cams[0].calib.height_px) + ")");
  }

  TrackRecordingResult out;
  out.frames = std::move(sink.frames);
  out.counters = system->counters();
  out.mapping_times_ns = system->mapping_times_ns();

  // World: the first body pose, optionally turned so z is up.
  const TimeNs t0_ns = out.frames.front().t_ns;
  std::optional<dsp::StaticImuEstimate> still;
  if (!rec.imu.empty()) {
    still = dsp::estimate_static_imu(rec.imu, t0_ns - kNsPerS / 2, t0_ns + kNsPerS / 2);
  }
  SE3d R_align = SE3d::Identity();
  if (options.gravity_aligned) {
    if (!still) throw InputError(name + ": gravity alignment needs IMU samples around the start");
    R_align.linear() = still->q_world_body.toRotationMatrix();
  }
  const SE3d& T_body_rect = system->tracker().T_body_rect();
  const SE3d T_out_tracker = R_align * T_body_rect;  // tracker world -> output world
  out.T_world_tracker = T_out_tracker;
  out.T_body_rect = T_body_rect;
  out.poses.reserve(out.frames.size());
  for (const dsp::TrackResult& r : out.frames) {
    out.poses.push_back(StampedPose{r.t_ns, T_out_tracker * r.T_world_cam * T_body_rect.inverse()});
  }
  if (map) {
    for (std::size_t i = 0; i < map->points.size(); ++i) {
      out.map.push_back((T_out_tracker * map->points.point(i).cast<double>()).cast<float>());
    }
    out.map.observations = map->points.observations;
    out.sigma_m = map->sigma_m;
    for (const Eigen::Vector3d& c : map->keyframe_centres) {
      out.keyframe_centres.push_back(T_out_tracker * c);
    }
  }

  std::optional<recording::GroundTruthState> gt0;
  if (!rec.ground_truth.empty()) gt0 = recording::ground_truth_at(rec.ground_truth, t0_ns);
  // "Up" in the output world, from the IMU and from the ground truth.
  if (still) {
    const Eigen::Vector3d up_imu = R_align.linear() * still->mean_accel_m_s2.normalized();
    std::optional<Eigen::Vector3d> up_gt;
    if (gt0) up_gt = R_align.linear() * gt0->up_body();
    out.floor = check_floor_of(out.map, up_imu, up_gt);
  }
  if (options.evaluate) {
    if (!gt0) throw InputError(name + ": no ground truth at the first frame");
    std::vector<StampedPose> gt;
    gt.reserve(rec.ground_truth.size());
    for (const recording::GroundTruthState& g : rec.ground_truth) {
      gt.push_back(StampedPose{g.t_ns, R_align * gt0->T_world_body.inverse() * g.T_world_body});
    }
    if (out.poses.size() >= 3) {
      dsp::TrajectoryEvalOptions eo;
      const double span_s = ns_to_s(out.poses.back().t_ns - out.poses.front().t_ns);
      eo.rpe_delta_s = std::clamp(span_s / 2.0, 0.05, 1.0);
      try {
        out.errors = dsp::evaluate_trajectory(out.poses, gt, eo);
      } catch (const std::invalid_argument&) {
        // Too few frames inside the ground truth's span: no ATE, the drift below still holds.
      }
    }
    if (const auto gt_last = recording::ground_truth_at(rec.ground_truth, out.poses.back().t_ns)) {
      const SE3d gt_rel = gt0->T_world_body.inverse() * gt_last->T_world_body;
      const SE3d est_rel = out.poses.front().T_world_body.inverse() * out.poses.back().T_world_body;
      const SE3d err = gt_rel.inverse() * est_rel;
      out.drift_m = err.translation().norm();
      out.drift_deg = Eigen::AngleAxisd(err.linear()).angle() * 180.0 / M_PI;
    }
  }
  return out;
}

}  // namespace wallar::firmware
