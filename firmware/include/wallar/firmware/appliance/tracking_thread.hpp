// SPDX-License-Identifier: Apache-2.0
/// @file tracking_thread.hpp
/// @brief The tracking module, the body of the tracking thread: drains the IMU ring into the
/// attitude filter and the gyro prior, tracks each frame it takes (TrackingAndMapping: the
/// tracker front end, mapping on its thread or in lock step), decides the degraded modes in
/// sensor time, publishes the pose, posts the view, keeps one record per frame, and in lock
/// step runs the reconstruction after key-frames.
///
/// Degraded modes (sensor time, so a replay reproduces them): no stereo frame for
/// `camera_timeout` of IMU time -> camera lost (the last visual pose turned by the attitude
/// filter's rotation since, position held; last wall model kept); no IMU sample for
/// `imu_timeout` of camera time after IMU samples were seen -> IMU lost (no gravity: 3-D wall
/// search; no gyro prior). A rig that never delivered an IMU sample is vision-only, not IMU
/// lost. Each transition is logged once and counted; both come back without a restart.
///
/// Storage: the per-frame records and the event list are reserved at construction; after
/// start-up the thread allocates nothing but the rare logged event (counting paused).
///
/// Threading: run() is the tracking thread's body; request_reset() from any thread; the
/// accessors marked "after the thread stopped" only once run() returned; the others any time.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "wallar/core/heartbeat.hpp"
#include "wallar/core/seqlock.hpp"
#include "wallar/dsp/imu/attitude_filter.hpp"
#include "wallar/firmware/appliance/pipeline_sink.hpp"
#include "wallar/firmware/appliance/reconstruction.hpp"
#include "wallar/firmware/appliance/records.hpp"
#include "wallar/firmware/appliance/snapshots.hpp"
#include "wallar/firmware/latency_histogram.hpp"
#include "wallar/firmware/live_view.hpp"
#include "wallar/firmware/log_ring.hpp"
#include "wallar/firmware/tracking_and_mapping.hpp"
#include "wallar/firmware/wakeup.hpp"

namespace wallar::firmware {

class LivePublisher;
class SharedPosePublisher;

struct TrackingThreadOptions {
  TrackingOptions tracking;  //!< tracker sizes, gyro prior, mapping thread or lock step
  /// Frames are handed over one by one (none overwritten): the frame tracked last alone says
  /// the camera is alive (repeatable). In real time the newest delivered frame counts too.
  bool every_frame = false;
  DurationNs camera_timeout_ns = 0;  //!< 0: max(4 frame periods, 200 ms)
  DurationNs imu_timeout_ns = 100 * kNsPerMs;
  std::size_t max_records = 1 << 16;  //!< per-frame records kept (the rest counted only)
  /// One record per event (transitions), formatted by the log thread; may be null.
  LogRing* log = nullptr;
  /// Test tooling (ApplianceOptions::before_frame): called before each frame; may be empty.
  std::function<void(TimeNs t_ns)> before_frame;
  /// ApplianceOptions::on_frame_pose: called after each frame taken; may be empty.
  std::function<void(const FramePose&)> on_frame_pose;
};

class TrackingThread {
 public:
  /// Throws std::invalid_argument for a calibration the tracker cannot use. `view` and
  /// `lockstep_reconstruction` may be null.
  TrackingThread(const RigCalibration& rig, const TrackingThreadOptions& options,
                 PipelineSink& pipeline, Wakeup& wakeup, Seqlock<PoseSnapshot>& pose,
                 LiveView* view, Reconstruction* lockstep_reconstruction);

  /// The thread's body, until `stop`; counts its allocations into `allocations`.
  void run(const std::atomic<bool>& stop, std::atomic<std::uint64_t>* allocations);
  void request_reset();
  /// The view to post to (null: none); before the thread starts.
  void set_view(LiveView* view) { view_ = view; }
  /// The live server to offer frames to (null: none); before the thread starts.
  void set_live(LivePublisher* live) { live_ = live; }
  /// The client API's shared pose (each pose, each IMU sample after it); before run().
  void set_client_pose(SharedPosePublisher* publisher, bool replay_clock) {
    client_pose_ = publisher;
    replay_clock_ = replay_clock;
  }
  /// After the thread stopped: stops mapping (global adjustment) and returns the final map.
  MapPtr finish() { return system_.finish(); }

  [[nodiscard]] TrackingAndMapping& system() { return system_; }
  [[nodiscard]] const TrackingAndMapping& system() const { return system_; }
  /// The thread's progress (a wake-up or a frame done: a loop), any thread: the supervisor
  /// withholds the watchdog while it is silent for over 2 s.
  [[nodiscard]] const Heartbeat& heartbeat() const { return heartbeat_; }
  [[nodiscard]] std::uint64_t wakeups() const { return wakeups_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t misses() const { return misses_.load(std::memory_order_relaxed); }
  [[nodiscard]] const LatencyHistogram& queue_latency() const { return queue_; }
  [[nodiscard]] const LatencyHistogram& track_time() const { return track_; }
  [[nodiscard]] const LatencyHistogram& imu_latency() const { return imu_latency_; }
  [[nodiscard]] DurationNs frame_period_ns() const { return frame_period_ns_; }
  // After the thread stopped.
  [[nodiscard]] const std::vector<PoseRecord>& records() const { return records_; }
  [[nodiscard]] const DegradedCounters& degraded() const { return degraded_; }
  /// "t=1.234 s: camera lost: ..." per event (formatted here, after the thread stopped).
  [[nodiscard]] std::vector<std::string> events() const;
  [[nodiscard]] std::uint64_t tracked() const { return tracked_; }
  [[nodiscard]] bool imu_seen() const { return imu_seen_; }

 private:
  void event(TimeNs t_ns, const char* what);
  void drain_imu(TimeNs until_ns);
  void on_imu(const ImuSample& s);
  void publish_imu_only(TimeNs t_ns);
  std::optional<Eigen::Vector3d> gravity_in_world(const SE3d& T_world_body) const;
  void on_frame(const StereoFrame& f);
  void do_reset();

  TrackingThreadOptions options_;
  PipelineSink& pipeline_;
  Wakeup& wakeup_;
  Seqlock<PoseSnapshot>& pose_;
  LiveView* view_;
  LivePublisher* live_ = nullptr;
  SharedPosePublisher* client_pose_ = nullptr;
  bool replay_clock_ = false;        //!< sensor time is a recording's, not CLOCK_MONOTONIC
  DurationNs sensor_offset_ns_ = 0;  //!< sensor clock - CLOCK_MONOTONIC (replay)
  Reconstruction* lockstep_reconstruction_;
  TrackingAndMapping system_;
  std::unique_ptr<dsp::AttitudeFilter> filter_;
  SE3d T_rect_body_;
  Eigen::Matrix3d R_body_imu_;
  DurationNs frame_period_ns_;
  DurationNs camera_timeout_ns_ = 0;

  TimeNs t0_ns_ = -1;
  TimeNs last_imu_t_ns_ = -1, last_frame_t_ns_ = -1, last_imu_only_t_ns_ = -1;
  bool imu_seen_ = false, imu_lost_ = false, camera_lost_ = false;
  SE3d last_T_world_body_ = SE3d::Identity();
  Eigen::Quaterniond q_world_imu_last_frame_ = Eigen::Quaterniond::Identity();
  Eigen::Quaterniond q_world_imu_at_loss_ = Eigen::Quaterniond::Identity();
  Eigen::Matrix3d R_world_body_at_loss_ = Eigen::Matrix3d::Identity();
  StereoFrame last_frame_;
  std::uint32_t epoch_ = 0;
  std::atomic<bool> reset_requested_{false};

  Heartbeat heartbeat_{Heartbeat::Kind::kLoop, monotonic_now_ns()};
  std::atomic<std::uint64_t> wakeups_{0};
  std::atomic<std::uint64_t> misses_{0};
  std::uint64_t tracked_ = 0;
  LatencyHistogram queue_, track_, imu_latency_;
  std::vector<PoseRecord> records_;
  DegradedCounters degraded_;
  std::vector<std::pair<TimeNs, const char*>> events_;  //!< since the first sample; reserved
  std::uint64_t events_dropped_ = 0;                    //!< beyond its capacity
};

}  // namespace wallar::firmware
