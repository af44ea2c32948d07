// SPDX-License-Identifier: Apache-2.0
/// @file offline.hpp
/// @brief The offline commands' side of the appliance (`wallar track`, `render`, `eval real`):
/// the appliance run over a recording, as fast as tracking goes, and its report in the world
/// of the commands' files, with the evaluation against the recording's ground truth (ATE, RPE,
/// drift) and the floor of the map against gravity.
///
/// World of the files: the first body pose (T_world_tracker = T_body_rect: the tracker's world
/// is its first rectified left camera), or with gravity_aligned that pose turned so z is up
/// (gravity from the IMU's still window around the first frame). `wallar run` writes its files
/// in the first body pose's world too, so `wallar track --lockstep` and `wallar run
/// --deterministic` give the same trajectory file.
///
/// Threading: call from one thread; run_over_recording() runs the appliance's threads itself.
#pragma once

#include <atomic>
#include <optional>
#include <vector>

#include "wallar/core/point_cloud.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/dsp/eval/trajectory.hpp"
#include "wallar/firmware/appliance.hpp"

namespace wallar::firmware {

/// What offline commands run with: `mode`, no view, no real-time priorities, the replay as
/// fast as the pipeline takes it, no log on stderr (the events are in the report), and a
/// supervisor and reconstruct thread that tick faster (10 ms, 50 ms).
ApplianceOptions offline_options(ApplianceMode mode);

/// The appliance over `rec`, as a replay board whose tracker sizes (and display) are `board`'s
/// (its source is not used: no board file is needed). Throws as run_appliance() does, and
/// InputError for a recording without stereo frames (naming it).
ApplianceReport run_over_recording(const recording::EurocRecording& rec, const BoardConfig& board,
                                   const ApplianceOptions& options, const std::atomic<bool>& stop);

/// The report's trajectory, map and walls in another world (T_world_tracker: the tracker's
/// world into it).
struct RunOutputs {
  SE3d T_world_tracker = SE3d::Identity();
  std::vector<StampedPose> poses;  //!< T_world_body, one per record (tracked, lost, rejected)
  PointCloud map;                  //!< observations = key-frames that saw each point
  std::vector<float> sigma_m;      //!< per map point
  std::vector<Eigen::Vector3d> keyframe_centres;
  std::optional<dsp::RoomResult> room;  //!< the reconstruction's final surfaces
};
RunOutputs outputs_in(const ApplianceReport& report, const SE3d& T_world_tracker);
/// In the first body pose's world.
inline RunOutputs outputs_in_body_world(const ApplianceReport& report) {
  return outputs_in(report, report.T_body_rect);
}

/// The run's outputs added to an MCAP recording as Foxglove messages (firmware/
/// foxglove_messages.hpp): /pose and /tf (world -> body) per record, the final /map and
/// /walls at the last record's time. `wallar track --mcap` and `wallar run --record` alike.
void write_outputs_mcap(recording::McapRecordingWriter& writer, const RunOutputs& outputs);

/// The rotation that turns the first body pose's world so z is up: gravity from the IMU's
/// still window of one second around `t0_ns`; none without IMU samples there.
std::optional<SE3d> gravity_alignment(const recording::EurocRecording& rec, TimeNs t0_ns);

struct FloorAgainstGravity {
  double distance_below_m = 0.0;  //!< the floor's distance below the first body pose
  std::size_t inliers = 0;
  double free_fit_vs_imu_deg = 0.0;  //!< the inliers' free 3-D plane fit against IMU gravity
  std::optional<double> free_fit_vs_ground_truth_deg;
};

struct RunEvaluationOptions {
  bool gravity_aligned = false;  //!< world z up (needs IMU samples around the first frame)
  bool ground_truth = false;     //!< ATE, RPE, drift (needs the recording's ground truth)
};

struct RunEvaluation {
  RunOutputs outputs;
  bool gravity_aligned = false;
  std::optional<dsp::TrajectoryErrors> errors;  //!< with ground_truth and >= 3 frames
  std::optional<double> drift_m, drift_deg;     //!< last pose relative to the first vs truth
  std::optional<FloorAgainstGravity> floor;     //!< when the IMU gives gravity and a floor is found
  /// The ground truth has positions only (every orientation the identity, as in GPS/INS
  /// position tracks): ATE is meaningful, RPE and drift (relative poses) are not and are left
  /// out.
  bool ground_truth_positions_only = false;
};

/// Checks before a run what evaluate_run() will need: ground truth with `ground_truth`;
/// throws InputError naming the recording otherwise.
void check_evaluation_inputs(const recording::EurocRecording& rec,
                             const RunEvaluationOptions& options);

/// The report of a run over `rec` in the world of the files, evaluated. Throws InputError when
/// no frame was taken, none could be tracked (saying why), or gravity alignment lacks IMU
/// samples around the start.
RunEvaluation evaluate_run(const recording::EurocRecording& rec, const ApplianceReport& report,
                           const RunEvaluationOptions& options);

}  // namespace wallar::firmware
