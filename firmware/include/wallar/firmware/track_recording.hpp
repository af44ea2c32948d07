// SPDX-License-Identifier: Apache-2.0
/// @file track_recording.hpp
/// @brief Tracking and mapping over a whole recording (what `wallar track` does): the poses
/// as T_world_body of the recording's body frame, the sparse map in the same world, and, with
/// ground truth, the errors (ATE, RPE, drift) and the floor of the map against gravity.
///
/// World frame: the first tracked body pose, or that pose turned so z is up (gravity from the
/// IMU's first second) when gravity_aligned.
///
/// Threading: call from one thread; it runs the mapping thread itself when asked to.
#pragma once

#include <atomic>
#include <optional>
#include <vector>

#include "wallar/core/point_cloud.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/eval/trajectory.hpp"
#include "wallar/firmware/tracking_and_mapping.hpp"

namespace wallar::firmware {

struct TrackRecordingOptions {
  TrackingOptions tracking;
  bool gravity_aligned = false;
  bool evaluate = false;  //!< needs ground truth (InputError otherwise)
};

struct FloorAgainstGravity {
  double distance_below_m = 0.0;  //!< the floor's distance below the first body pose
  std::size_t inliers = 0;
  double free_fit_vs_imu_deg = 0.0;  //!< the inliers' free 3-D plane fit against IMU gravity
  std::optional<double> free_fit_vs_ground_truth_deg;
};

struct TrackRecordingResult {
  std::vector<dsp::TrackResult> frames;
  std::vector<StampedPose> poses;  //!< T_world_body, one per frame
  /// The tracker's own world (its first rectified left camera) into this result's world, and
  /// the body-to-rectified-camera transform: T_world_body = T_world_tracker * T_tracker_cam *
  /// T_body_rect^-1 for any TrackResult of a tracker started on the same first frame.
  SE3d T_world_tracker = SE3d::Identity();
  SE3d T_body_rect = SE3d::Identity();
  PointCloud map;                  //!< world frame, observations = key-frames that saw it
  std::vector<float> sigma_m;      //!< per map point
  std::vector<Eigen::Vector3d> keyframe_centres;  //!< world frame (of the body)
  TrackingCounters counters;
  std::vector<std::int64_t> mapping_times_ns;
  std::optional<dsp::TrajectoryErrors> errors;  //!< with evaluate and >= 3 frames
  std::optional<double> drift_m, drift_deg;     //!< last pose relative to the first vs truth
  std::optional<FloorAgainstGravity> floor;     //!< when the IMU gives gravity and a floor is found
};

/// Tracks the recording as fast as possible. Throws InputError for a recording without stereo
/// pairs, a calibration the tracker cannot use (naming the recording), or evaluate without
/// ground truth.
TrackRecordingResult track_recording(const recording::EurocRecording& recording,
                                     const TrackRecordingOptions& options,
                                     const std::atomic<bool>& stop);

}  // namespace wallar::firmware
