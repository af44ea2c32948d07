// SPDX-License-Identifier: Apache-2.0
/// @file tracking_thread.cpp
/// @brief The tracking thread: IMU filter, tracker and mapping, degraded modes, pose and view.
#include "wallar/firmware/appliance/tracking_thread.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <limits>

#include "wallar/firmware/appliance/allocation_count.hpp"
#include "wallar/firmware/appliance/client_server.hpp"
#include "wallar/firmware/appliance/live_publisher.hpp"
#include "wallar/firmware/appliance/source_module.hpp"
#include "wallar/firmware/imu_attitude.hpp"

namespace wallar::firmware {
namespace {

/// A copy of `image` in a heap buffer of its own (empty stays empty).
Image heap_copy(const Image& image) {
  if (image.empty()) return image;
  Image copy = Image::allocate(image.width(), image.height(), image.format());
  const auto row_bytes = static_cast<std::size_t>(image.width()) *
                         static_cast<std::size_t>(bytes_per_pixel(image.format()));
  for (int y = 0; y < image.height(); ++y)
    std::memcpy(copy.mutable_data() + static_cast<std::ptrdiff_t>(y) * copy.stride_bytes(),
                image.row(y), row_bytes);
  return copy;
}

constexpr const char* kCameraLostHud = "no new images: walls hidden, map kept";
constexpr const char* kImuLostHud = "IMU lost: 3-D wall search, no gyro prior";

// The tracker's stage clock (dsp reads none itself): per-frame stage times for the records.
std::int64_t tracker_clock_ns() { return monotonic_now_ns(); }

}  // namespace

TrackingThread::TrackingThread(const RigCalibration& rig, const TrackingThreadOptions& options,
                               PipelineSink& pipeline, Wakeup& wakeup, Seqlock<PoseSnapshot>& pose,
                               LiveView* view, Reconstruction* lockstep_reconstruction)
    : options_(options),
      pipeline_(pipeline),
      wakeup_(wakeup),
      pose_(pose),
      view_(view),
      lockstep_reconstruction_(lockstep_reconstruction),
      system_(rig, options.tracking, &tracker_clock_ns),
      T_rect_body_(system_.tracker().T_body_rect().inverse()),
      R_body_imu_(rig.imu.T_body_imu.linear()),
      frame_period_ns_(frame_period_of(rig.cams[0])) {
  filter_ = std::make_unique<dsp::AttitudeFilter>(attitude_config_for(rig.imu));
  camera_timeout_ns_ = options.camera_timeout_ns > 0
                           ? options.camera_timeout_ns
                           : std::max<DurationNs>(4 * frame_period_ns_, 200 * kNsPerMs);
  records_.reserve(options.max_records);
  events_.reserve(256);
}

void TrackingThread::run(const std::atomic<bool>& stop, std::atomic<std::uint64_t>* allocations) {
  tl_allocation_counter = allocations;
  StereoFrame frame;
  while (!stop.load(std::memory_order_acquire)) {
    wakeup_.wait_for(10 * kNsPerMs);
    heartbeat_.beat(monotonic_now_ns());
    wakeups_.fetch_add(1, std::memory_order_relaxed);
    if (reset_requested_.exchange(false)) do_reset();
    // Frames first, each after the IMU samples up to its time (they arrived before it); then
    // the samples after the newest frame. A tracker that fell behind thus never reads the IMU
    // running ahead of a frame still waiting as a lost camera.
    while (pipeline_.take_frame(frame)) {
      // A tracker slower than the camera never leaves this loop (a frame is always waiting):
      // a reset asked for meanwhile (the remote's R) applies before the next frame, not when
      // the camera stops (found under emulation: a key press waited until a camera was pulled).
      if (reset_requested_.exchange(false)) do_reset();
      drain_imu(frame.t_ns);
      on_frame(frame);
      frame = StereoFrame{};  // give the buffers back now
      pipeline_.frame_done();
      // A frame done is progress too: a tracker slower than the camera never leaves this loop
      // (a new frame is always waiting), and must not read as hung (seen under emulation).
      heartbeat_.beat(monotonic_now_ns());
    }
    drain_imu(std::numeric_limits<TimeNs>::max());
  }
  tl_allocation_counter = nullptr;
}

void TrackingThread::request_reset() {
  reset_requested_.store(true);
  wakeup_.notify();
}

void TrackingThread::event(TimeNs t_ns, const char* what) {
  // No formatting here (a SCHED_FIFO thread): the time and the static text are kept and
  // posted; the log thread and events() make the lines.
  const TimeNs since_ns = t0_ns_ >= 0 ? t_ns - t0_ns_ : 0;
  if (events_.size() < events_.capacity()) {
    events_.emplace_back(since_ns, what);
  } else {
    ++events_dropped_;
  }
  if (options_.log != nullptr) options_.log->post("t=%.3f s: %s", {ns_to_s(since_ns), what});
}

std::vector<std::string> TrackingThread::events() const {
  std::vector<std::string> out;
  out.reserve(events_.size() + 1);
  char line[200];
  for (const auto& [since_ns, what] : events_) {
    std::snprintf(line, sizeof line, "t=%.3f s: %s", ns_to_s(since_ns), what);
    out.emplace_back(line);
  }
  if (events_dropped_ > 0) out.push_back(std::to_string(events_dropped_) + " more events");
  return out;
}

void TrackingThread::drain_imu(TimeNs until_ns) {
  bool popped = false;
  while (ImuSample* s = pipeline_.imu_front()) {
    if (s->t_ns > until_ns) break;
    const ImuSample sample = *s;
    pipeline_.imu_pop();
    popped = true;
    on_imu(sample);
  }
  if (popped) pipeline_.imu_room();
}

void TrackingThread::on_imu(const ImuSample& s) {
  if (t0_ns_ < 0) t0_ns_ = s.t_ns;
  if (s.publish_t_ns > 0) imu_latency_.record(monotonic_now_ns() - s.publish_t_ns);
  system_.on_imu(s);
  filter_->update(s);
  if (filter_->initialized()) system_.set_gyro_bias(filter_->gyro_bias_rad_s());
  last_imu_t_ns_ = s.t_ns;
  imu_seen_ = true;
  if (client_pose_ != nullptr) {
    // The client API's prediction: the bias-corrected rate since the last pose (a store into
    // shared memory; no system call, no allocation).
    const Eigen::Vector3d bias = filter_->initialized()
                                     ? Eigen::Vector3d(filter_->gyro_bias_rad_s())
                                     : Eigen::Vector3d::Zero();
    client_pose_->on_imu(s.t_ns, R_body_imu_ * (s.gyro_rad_s - bias));
  }
  if (imu_lost_) {
    imu_lost_ = false;
    ++degraded_.imu_recovered;
    event(s.t_ns, "IMU back: gravity-aligned walls and gyro prior again");
  }
  if (last_frame_t_ns_ < 0) return;
  // The camera is alive while frames arrive, tracked or not: in real time the newest delivered
  // frame counts too (overwritten while tracking was busy). When every frame is handed over in
  // order, the tracked one alone decides (repeatable).
  const TimeNs last_seen_t_ns = options_.every_frame
                                    ? last_frame_t_ns_
                                    : std::max(last_frame_t_ns_, pipeline_.last_delivered_t_ns());
  if (!camera_lost_ && s.t_ns - last_seen_t_ns > camera_timeout_ns_) {
    camera_lost_ = true;
    ++degraded_.camera_lost;
    event(s.t_ns,
          "camera lost: the last image shown frozen, IMU-only orientation, map and walls kept");
    {
      // The frozen image drawn from now on is a copy, so the lost camera's kernel buffers go
      // back now: a device may come back only once its old queue is released (vivid's
      // disconnect waits for every handle, mappings included), and a gone device's memory is
      // freed either way. A rare transition, allowed to allocate like a reset.
      const AllocationPause pause;
      last_frame_.left.image = heap_copy(last_frame_.left.image);
      last_frame_.right.image = heap_copy(last_frame_.right.image);
    }
    R_world_body_at_loss_ = last_T_world_body_.linear();
    q_world_imu_at_loss_ = q_world_imu_last_frame_;
    last_imu_only_t_ns_ = -1;
  }
  if (camera_lost_ && filter_->initialized() &&
      (last_imu_only_t_ns_ < 0 || s.t_ns - last_imu_only_t_ns_ >= frame_period_ns_)) {
    publish_imu_only(s.t_ns);
  }
}

void TrackingThread::publish_imu_only(TimeNs t_ns) {
  // Camera lost: the last visual pose turned by the IMU's rotation since, position held.
  last_imu_only_t_ns_ = t_ns;
  const Eigen::Matrix3d R_imu0_imu =
      (q_world_imu_at_loss_.conjugate() * filter_->q_world_imu()).toRotationMatrix();
  SE3d T = last_T_world_body_;
  T.linear() = R_world_body_at_loss_ * R_body_imu_ * R_imu0_imu * R_body_imu_.transpose();
  const std::optional<Eigen::Vector3d> down = gravity_in_world(T);
  pose_.store(make_pose_snapshot(t_ns, T, dsp::TrackingState::kTracking, down, epoch_, true));
  if (client_pose_ != nullptr) {
    client_pose_->on_pose(t_ns, T, client_wire::Tracking::kTracking, epoch_, sensor_offset_ns_);
  }
  ++degraded_.imu_only_poses;
  if (view_ != nullptr && !last_frame_.left.image.empty()) {
    ViewPost post;
    post.frame = last_frame_;
    post.capture_t_ns = monotonic_now_ns();
    post.T_world_body = T;
    post.state = dsp::TrackingState::kTracking;
    post.degraded = kCameraLostHud;
    post.camera_lost = true;  // drawn frozen: dark red, no walls over a still picture
    view_->post(std::move(post));
  }
}

std::optional<Eigen::Vector3d> TrackingThread::gravity_in_world(const SE3d& T_world_body) const {
  if (imu_lost_ || !filter_->initialized()) return std::nullopt;
  return (T_world_body.linear() * R_body_imu_ * filter_->gravity_dir_imu()).normalized();
}

void TrackingThread::on_frame(const StereoFrame& f) {
  if (t0_ns_ < 0) t0_ns_ = f.t_ns;
  if (options_.before_frame) options_.before_frame(f.t_ns);
  const TimeNs taken_ns = monotonic_now_ns();
  if (f.left.publish_t_ns > 0) queue_.record(taken_ns - f.left.publish_t_ns);
  if (camera_lost_) {
    camera_lost_ = false;
    ++degraded_.camera_recovered;
    event(f.t_ns, "camera back: visual tracking again");
  }
  if (imu_seen_ && !imu_lost_ && f.t_ns - last_imu_t_ns_ > options_.imu_timeout_ns) {
    imu_lost_ = true;
    ++degraded_.imu_lost;
    event(f.t_ns, "IMU lost: 3-D wall search, tracking without the gyro");
  }
  const dsp::TrackResult r = system_.on_stereo(f);
  const DurationNs took = monotonic_now_ns() - taken_ns;
  track_.record(took);
  if (took > frame_period_ns_) misses_.fetch_add(1, std::memory_order_relaxed);
  // Every frame taken has its record, a rejected one too (the pose it holds, and why).
  const SE3d T_world_body = r.T_world_cam * T_rect_body_;
  if (records_.size() < records_.capacity()) {
    records_.push_back({f.t_ns, T_world_body, r.state, r.rejected, r.keyframe, r.times});
  }
  if (options_.on_frame_pose) {
    // In the first body pose's world, as the commands' files (T_body_rect: the tracker's world).
    options_.on_frame_pose({f.t_ns, f.left.publish_t_ns, taken_ns,
                            system_.tracker().T_body_rect() * T_world_body, r.state,
                            r.rejected != nullptr, r.times, &system_.tracker()});
  }
  if (r.rejected != nullptr) return;
  ++tracked_;
  last_frame_t_ns_ = f.t_ns;
  last_frame_ = f;
  if (r.state == dsp::TrackingState::kTracking) {
    last_T_world_body_ = T_world_body;
    if (filter_->initialized()) q_world_imu_last_frame_ = filter_->q_world_imu();
  }
  const std::optional<Eigen::Vector3d> down = gravity_in_world(T_world_body);
  pose_.store(make_pose_snapshot(f.t_ns, T_world_body, r.state, down, epoch_, false));
  if (client_pose_ != nullptr) {
    // A replay's clock is the recording's: the frame's delivery (CLOCK_MONOTONIC) maps it.
    if (replay_clock_ && f.left.publish_t_ns > 0) sensor_offset_ns_ = f.t_ns - f.left.publish_t_ns;
    const auto state = r.state == dsp::TrackingState::kTracking ? client_wire::Tracking::kTracking
                       : r.state == dsp::TrackingState::kLost
                           ? client_wire::Tracking::kLost
                           : client_wire::Tracking::kInitialising;
    client_pose_->on_pose(f.t_ns, T_world_body, state, epoch_, sensor_offset_ns_);
  }
  if (view_ != nullptr) {
    ViewPost post;
    post.frame = f;
    post.capture_t_ns = f.left.publish_t_ns;
    post.T_world_body = T_world_body;
    post.state = r.state;
    post.degraded = imu_lost_ ? kImuLostHud : nullptr;
    view_->post(std::move(post));
  }
  if (live_ != nullptr) live_->offer_frame(f);
  if (lockstep_reconstruction_ != nullptr && r.keyframe) {
    // Lock step: the walls at fixed points of the stream (after key-frames).
    const AllocationPause pause;
    if (const MapPtr map = system_.latest_map()) {
      lockstep_reconstruction_->maybe_run(*map, down, epoch_, false);
    }
  }
}

void TrackingThread::do_reset() {
  const AllocationPause pause;  // a reset rebuilds the mapper: allowed to allocate
  system_.reset();
  ++epoch_;
  ++degraded_.resets;
  last_frame_ = StereoFrame{};
  event(last_frame_t_ns_ >= 0 ? last_frame_t_ns_ : 0, "reset: tracking and map start again");
}

}  // namespace wallar::firmware
