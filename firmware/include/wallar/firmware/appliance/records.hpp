// SPDX-License-Identifier: Apache-2.0
/// @file records.hpp
/// @brief The plain data the appliance's modules report: one record per frame the tracking
/// module took, the degraded-mode counters, and the rows of the stats table.
///
/// Threading: plain values; copy them where they are needed.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/firmware/latency_histogram.hpp"

namespace wallar::firmware {

/// One frame the tracking module took, tracked or not.
struct PoseRecord {
  TimeNs t_ns = 0;
  /// The body in the tracker's world (its first rectified left camera); for a frame that was
  /// lost or rejected, the last pose the tracker holds (never NaN).
  SE3d T_world_body = SE3d::Identity();
  dsp::TrackingState state = dsp::TrackingState::kInitialising;
  /// Why the frame was not used (a static string: wrong size or format), or null.
  const char* rejected = nullptr;
  bool keyframe = false;
  dsp::TrackerTimes times;  //!< the tracker's stage times for this frame
};

/// One frame's outcome as an embedder gets it (ApplianceOptions::on_frame_pose, the VIT
/// library): the body in the first body pose's world (the world of `wallar track`'s files),
/// and when the frame was handed on, taken and done.
struct FramePose {
  TimeNs t_ns = 0;  //!< the frame's (left image's) sensor time
  TimeNs publish_t_ns =
      0;                //!< CLOCK_MONOTONIC when the source handed the left image on (0: unknown)
  TimeNs taken_ns = 0;  //!< CLOCK_MONOTONIC when the tracking thread took the frame
  SE3d T_world_body =
      SE3d::Identity();  //!< first body pose's world; the last pose when not tracked
  dsp::TrackingState state = dsp::TrackingState::kInitialising;
  bool rejected = false;    //!< not used (wrong size or format)
  dsp::TrackerTimes times;  //!< the tracker's stage times for this frame
  /// The tracker that took the frame, for what it measured there (Tracker::frame_features);
  /// valid during the call only, on the tracking thread.
  const dsp::Tracker* tracker = nullptr;
};

struct DegradedCounters {
  std::uint64_t camera_lost = 0, camera_recovered = 0, imu_lost = 0, imu_recovered = 0;
  std::uint64_t imu_only_poses = 0;   //!< poses published from the IMU alone
  std::uint64_t faults_injected = 0;  //!< frames/samples withheld or corrupted (test tooling)
  std::uint64_t resets = 0;
};

struct ThreadRow {
  std::string name;
  std::string policy;  //!< "FIFO 80" or "OTHER"
  int cpu = -1;
  double cpu_s = 0.0;
  double cpu_percent = 0.0;  //!< of one core over the run
  std::uint64_t wakeups = 0;
  std::uint64_t misses = 0;
  std::optional<std::uint64_t> allocations;  //!< after start-up (when counted in this build)
  std::string note;                          //!< fallback reason or role
};

struct StageRow {
  std::string name;
  LatencySummary latency;
  DurationNs deadline_ns = 0;  //!< 0: none
  std::uint64_t misses = 0;    //!< samples over the deadline
};

}  // namespace wallar::firmware
