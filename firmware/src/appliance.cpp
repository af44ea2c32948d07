// SPDX-License-Identifier: Apache-2.0
/// @file appliance.cpp
/// @brief The supervisor and its modules: source, tracking (with the IMU filter and the
/// degraded modes), reconstruction, render; channels between them; the thread table.
#include "wallar/firmware/appliance.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>

#include "wallar/core/error.hpp"
#include "wallar/core/mailbox.hpp"
#include "wallar/core/seqlock.hpp"
#include "wallar/core/spsc_ring.hpp"
#include "wallar/core/triple_buffer.hpp"
#include "wallar/drivers/bus/gpio.hpp"
#include "wallar/drivers/input/evdev_keys.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/imu/attitude_filter.hpp"
#include "wallar/firmware/imu_attitude.hpp"
#include "wallar/firmware/live_imu.hpp"
#include "wallar/firmware/live_stereo.hpp"
#include "wallar/firmware/periodic.hpp"
#include "wallar/firmware/rt_thread.hpp"
#include "wallar/firmware/systemd_notify.hpp"
#include "wallar/firmware/wakeup.hpp"

namespace wallar::firmware {

thread_local std::atomic<std::uint64_t>* tl_allocation_counter = nullptr;
bool g_allocations_counted = false;

namespace {

// ---------------------------------------------------------------------------------------------
// The thread table: every thread the appliance starts, in one place. Priorities apply only when
// the board runs in real time and the system permits SCHED_FIFO (else SCHED_OTHER, warned once).
// The renderer stays SCHED_OTHER: Mesa's llvmpipe starts worker threads that would inherit a
// real-time policy and starve the rest on a small board.
struct ThreadTableEntry {
  const char* name;
  int priority;
  int cpu;
  std::size_t stack_bytes;
  const char* role;
};
constexpr std::size_t kMiB = 1024 * 1024;
constexpr ThreadTableEntry kThreadTable[] = {
    {"imu", 80, -1, 1 * kMiB, "IMU driver: FIFO, time stamps"},
    {"capture", 70, -1, 1 * kMiB, "V4L2 capture and stereo pairing"},
    {"replay", 70, -1, 2 * kMiB, "recording played as the sensors"},
    {"tracking", 60, -1, 4 * kMiB, "IMU filter, tracker, degraded modes"},
    {"mapping", 0, -1, 8 * kMiB, "key-frames, bundle adjustment"},
    {"reconstruct", 0, -1, 4 * kMiB, "walls, floor, ceiling"},
    {"render", 0, -1, 4 * kMiB, "headset view (EGL)"},
    {"supervisor", 0, -1, 0, "health, stop, stats, watchdog (main thread)"},
};

const ThreadTableEntry& table_entry(const char* name) {
  for (const ThreadTableEntry& e : kThreadTable) {
    if (std::string_view(e.name) == name) return e;
  }
  throw std::logic_error(std::string("thread table has no ") + name);
}

ThreadSpec spec_of(const char* name, bool realtime) {
  const ThreadTableEntry& e = table_entry(name);
  ThreadSpec s;
  s.name = e.name;
  s.priority = realtime ? e.priority : 0;
  s.cpu = e.cpu;
  s.stack_bytes = e.stack_bytes;
  return s;
}

/// The camera's frame period (20 Hz when its rate is unknown).
DurationNs frame_period_of(const CameraCalibration& cam) {
  return cam.rate_hz > 0 ? static_cast<DurationNs>(1e9 / cam.rate_hz) : 50 * kNsPerMs;
}

void default_log(const std::string& line) { std::fprintf(stderr, "wallar: %s\n", line.c_str()); }

/// Resident memory now [KiB], read from /proc without allocating (the supervisor's tick).
long current_rss_kb() {
  const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  char buf[128];
  const ssize_t n = ::read(fd, buf, sizeof buf - 1);
  ::close(fd);
  if (n <= 0) return 0;
  buf[n] = 0;
  long size = 0, resident = 0;
  if (std::sscanf(buf, "%ld %ld", &size, &resident) != 2) return 0;
  return resident * (sysconf(_SC_PAGESIZE) / 1024);
}

long max_rss_kb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

// ---------------------------------------------------------------------------------------------
// Channels from the source toward tracking.

constexpr std::size_t kImuRingSlots = 4096;  // 20 s at 200 Hz: drops only if tracking hangs

/// Where sources deliver. The IMU goes through an SPSC ring (every sample matters; a full ring
/// drops and counts, or in deterministic mode waits); frames through a newest-only mailbox.
/// Producers never allocate. Threading: on_imu from one thread, on_stereo from one thread.
class PipelineSink final : public source::SensorSink, public drivers::ImuSampleSink {
 public:
  PipelineSink(Wakeup& tracking, const std::atomic<bool>& stop, bool deterministic)
      : tracking_(tracking), stop_(stop), deterministic_(deterministic), imu_(kImuRingSlots) {}

  void on_imu(const ImuSample& s) override {
    ImuSample* slot = imu_.producer_slot();
    while (slot == nullptr && deterministic_ && !stop_.load(std::memory_order_acquire)) {
      tracking_.notify();
      taken_.wait_for(kNsPerMs);
      slot = imu_.producer_slot();
    }
    if (slot == nullptr) {
      imu_dropped_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    *slot = s;
    imu_.push();
    imu_in_.fetch_add(1, std::memory_order_relaxed);
    // Wake tracking every 5 ms of sensor time (it also wakes on its own every 10 ms).
    if (s.t_ns - last_imu_notify_t_ns_ >= 5 * kNsPerMs) {
      last_imu_notify_t_ns_ = s.t_ns;
      tracking_.notify();
    }
  }
  void on_imu_sample(const ImuSample& s) noexcept override { on_imu(s); }
  void on_stereo(const StereoFrame& f) override {
    last_delivered_t_ns_.store(f.t_ns, std::memory_order_relaxed);
    frames_.post(f);
    frames_in_.fetch_add(1, std::memory_order_release);
    tracking_.notify();
    if (!deterministic_) return;
    // Lock step: wait until tracking took this frame, so none is overwritten.
    while (frames_taken_.load(std::memory_order_acquire) < frames_in_.load() &&
           !stop_.load(std::memory_order_acquire)) {
      taken_.wait_for(50 * kNsPerMs);
    }
  }
  void on_unpaired(int /*cam*/, const CameraFrame& /*f*/) override {
    unpaired_.fetch_add(1, std::memory_order_relaxed);
  }

  // Consumer side (tracking thread).
  ImuSample* imu_front() { return imu_.front(); }
  void imu_pop() { imu_.pop(); }
  bool take_frame(StereoFrame& out) { return frames_.take(out); }
  void frame_done() {
    frames_taken_.fetch_add(1, std::memory_order_release);
    if (deterministic_) taken_.notify();
  }
  void imu_room() {
    if (deterministic_) taken_.notify();
  }
  void release_producers() { taken_.notify(); }
  /// Frames delivered but neither tracked nor overwritten yet, and samples in the ring.
  [[nodiscard]] bool drained() const {
    return frames_taken_.load() + frames_.overwritten() >= frames_in_.load() &&
           imu_.size_approx() == 0;
  }

  [[nodiscard]] std::uint64_t imu_in() const { return imu_in_.load(); }
  [[nodiscard]] std::uint64_t imu_dropped() const { return imu_dropped_.load(); }
  [[nodiscard]] std::uint64_t frames_in() const { return frames_in_.load(); }
  [[nodiscard]] std::uint64_t frames_overwritten() const { return frames_.overwritten(); }
  [[nodiscard]] std::uint64_t unpaired() const { return unpaired_.load(); }
  /// Sensor time of the newest frame delivered (taken or not); -1 before the first.
  [[nodiscard]] TimeNs last_delivered_t_ns() const {
    return last_delivered_t_ns_.load(std::memory_order_relaxed);
  }

 private:
  Wakeup& tracking_;
  const std::atomic<bool>& stop_;
  bool deterministic_;
  SpscRing<ImuSample> imu_;
  NewestMailbox<StereoFrame> frames_;
  Wakeup taken_;
  TimeNs last_imu_notify_t_ns_ = 0;
  std::atomic<TimeNs> last_delivered_t_ns_{-1};
  std::atomic<std::uint64_t> imu_in_{0}, imu_dropped_{0}, frames_in_{0}, frames_taken_{0},
      unpaired_{0};
};

/// Shifts a replayed loop's time stamps past the previous loop's, so time keeps increasing, and
/// ends the IMU stream with the cameras' (a recording's IMU often runs on after its last
/// frame, which would read as a lost camera at every loop's end).
class LoopShift final : public source::SensorSink {
 public:
  LoopShift(source::SensorSink& next, TimeNs imu_end_ns) : next_(next), imu_end_ns_(imu_end_ns) {}
  void set_offset(DurationNs offset_ns) { offset_ns_ = offset_ns; }
  void on_imu(const ImuSample& s) override {
    if (s.t_ns > imu_end_ns_) return;
    if (offset_ns_ == 0) return next_.on_imu(s);
    ImuSample shifted = s;
    shifted.t_ns += offset_ns_;
    next_.on_imu(shifted);
  }
  void on_stereo(const StereoFrame& f) override {
    if (offset_ns_ == 0) return next_.on_stereo(f);
    StereoFrame shifted = f;  // counted references: no pixels copied
    shifted.t_ns += offset_ns_;
    shifted.left.t_ns += offset_ns_;
    shifted.right.t_ns += offset_ns_;
    next_.on_stereo(shifted);
  }
  void on_unpaired(int cam, const CameraFrame& f) override { next_.on_unpaired(cam, f); }

 private:
  source::SensorSink& next_;
  TimeNs imu_end_ns_;
  DurationNs offset_ns_ = 0;
};

/// Withholds or corrupts samples at the planned sensor times (hardware-in-the-loop tests).
class FaultSink final : public source::SensorSink {
 public:
  FaultSink(source::SensorSink& next, std::vector<FaultSpec> faults)
      : next_(next), faults_(std::move(faults)), corrupted_(faults_.size(), false) {}
  void on_imu(const ImuSample& s) override {
    if (t0_ns_ < 0) t0_ns_ = s.t_ns;
    if (active(FaultSpec::Kind::kImuUnplug, s.t_ns)) {
      injected_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    next_.on_imu(s);
  }
  void on_stereo(const StereoFrame& f) override {
    if (t0_ns_ < 0) t0_ns_ = f.t_ns;
    if (active(FaultSpec::Kind::kCameraStall, f.t_ns)) {
      injected_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    for (std::size_t i = 0; i < faults_.size(); ++i) {
      const FaultSpec& fault = faults_[i];
      if (fault.kind != FaultSpec::Kind::kCorruptFrame || corrupted_[i]) continue;
      if (f.t_ns < t0_ns_ + s_to_ns(fault.at_s)) continue;
      corrupted_[i] = true;
      injected_.fetch_add(1, std::memory_order_relaxed);
      StereoFrame bad = f;
      bad.left.image = noise_like(f.left.image);  // a garbled transfer: right size, no content
      next_.on_stereo(bad);
      return;
    }
    next_.on_stereo(f);
  }
  void on_unpaired(int cam, const CameraFrame& f) override { next_.on_unpaired(cam, f); }
  [[nodiscard]] std::uint64_t injected() const { return injected_.load(); }

 private:
  bool active(FaultSpec::Kind kind, TimeNs t_ns) const {
    for (const FaultSpec& fault : faults_) {
      if (fault.kind != kind) continue;
      const TimeNs begin = t0_ns_ + s_to_ns(fault.at_s);
      if (t_ns >= begin && t_ns < begin + s_to_ns(fault.duration_s)) return true;
    }
    return false;
  }
  Image noise_like(const Image& like) {
    Image out =
        Image::allocate(std::max(like.width(), 1), std::max(like.height(), 1), PixelFormat::kGray8);
    for (int y = 0; y < out.height(); ++y) {
      std::uint8_t* row = out.mutable_data() + std::ptrdiff_t{y} * out.stride_bytes();
      for (int x = 0; x < out.width(); ++x) {
        lcg_ = lcg_ * 6364136223846793005ULL + 1442695040888963407ULL;
        row[x] = static_cast<std::uint8_t>(lcg_ >> 56);
      }
    }
    return out;
  }

  source::SensorSink& next_;
  std::vector<FaultSpec> faults_;
  std::vector<bool> corrupted_;
  TimeNs t0_ns_ = -1;
  std::uint64_t lcg_ = 0x853c49e6748fea9bULL;
  std::atomic<std::uint64_t> injected_{0};
};

// ---------------------------------------------------------------------------------------------
// Snapshots.

/// The pose channel's value (trivially copyable for the seqlock).
struct PoseSnapshot {
  TimeNs t_ns = 0;
  double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  // column-major R_world_body
  double p[3] = {0, 0, 0};
  double down_world[3] = {0, 0, 0};
  std::uint32_t epoch = 0;  //!< +1 at each reset (the map restarts)
  std::uint8_t state = 0;
  bool has_down = false;
  bool imu_only = false;
};

PoseSnapshot make_pose_snapshot(TimeNs t_ns, const SE3d& T, dsp::TrackingState state,
                                const std::optional<Eigen::Vector3d>& down, std::uint32_t epoch,
                                bool imu_only) {
  PoseSnapshot s;
  s.t_ns = t_ns;
  Eigen::Map<Eigen::Matrix3d>(s.R) = T.linear();
  Eigen::Map<Eigen::Vector3d>(s.p) = T.translation();
  if (down) {
    Eigen::Map<Eigen::Vector3d>(s.down_world) = *down;
    s.has_down = true;
  }
  s.epoch = epoch;
  s.state = static_cast<std::uint8_t>(state);
  s.imu_only = imu_only;
  return s;
}

using MapPtr = std::shared_ptr<const dsp::MapSnapshot>;

// ---------------------------------------------------------------------------------------------
// Scene reconstruction: re-runs when the map grew, warm-started from the last model (ids kept),
// 2-D with gravity, 3-D without. Not thread-safe: one thread at a time (the reconstruction
// thread, or the tracking thread in deterministic mode; the supervisor after both stopped).

class Reconstruction {
 public:
  Reconstruction(const ApplianceOptions& options, std::size_t max_points,
                 TripleBuffer<WallModel>& out)
      : options_(options), estimator_(std::max<std::size_t>(max_points, 1)), out_(out) {}

  /// Runs when the map grew enough since the last run (or `force`); returns whether it ran.
  bool maybe_run(const dsp::MapSnapshot& map, const std::optional<Eigen::Vector3d>& down,
                 std::uint32_t epoch, bool force) {
    if (epoch != epoch_) {  // the map was reset: the old walls are no warm start
      epoch_ = epoch;
      previous_.reset();
      last_points_ = 0;
    }
    const std::size_t n = map.points.size();
    if (n < options_.min_map_points) return false;
    const bool grown = last_points_ == 0 ||
                       static_cast<double>(n) >=
                           static_cast<double>(last_points_) * (1.0 + options_.regrow_fraction);
    if (!grown && !(force && n != last_points_) && !(force && down.has_value() != last_gravity_)) {
      return false;
    }
    dsp::RoomConfig config = dsp::room_config_for_map(
        map.keyframe_centres, down, options_.wall_threshold_m, options_.max_surfaces);
    config.detector.method = options_.wall_method;
    config.detector.seed = options_.seed + runs_;
    const TimeNs t0 = monotonic_now_ns();
    dsp::RoomResult result =
        estimator_.estimate(map.points, config, previous_ ? &*previous_ : nullptr);
    time_.record(monotonic_now_ns() - t0);
    previous_ = result.model;
    last_points_ = n;
    last_gravity_ = down.has_value();
    ++runs_;
    out_.back() = result.model;
    out_.publish();
    result_ = std::move(result);
    return true;
  }

  [[nodiscard]] const std::optional<dsp::RoomResult>& result() const { return result_; }
  [[nodiscard]] bool gravity() const { return last_gravity_; }
  [[nodiscard]] std::uint64_t runs() const { return runs_; }
  [[nodiscard]] const LatencyHistogram& time() const { return time_; }

 private:
  const ApplianceOptions& options_;
  dsp::RoomEstimator estimator_;
  TripleBuffer<WallModel>& out_;
  std::optional<WallModel> previous_;
  std::optional<dsp::RoomResult> result_;
  std::size_t last_points_ = 0;
  bool last_gravity_ = false;
  std::uint32_t epoch_ = 0;
  std::uint64_t runs_ = 0;
  LatencyHistogram time_;
};

std::optional<Eigen::Vector3d> down_of(const PoseSnapshot& s) {
  if (!s.has_down) return std::nullopt;
  return Eigen::Vector3d(s.down_world[0], s.down_world[1], s.down_world[2]);
}

// ---------------------------------------------------------------------------------------------
// The tracking module: drains the IMU ring (gyro prior, attitude filter), tracks frames, decides
// the degraded modes in sensor time, publishes the pose and posts the view.

constexpr std::size_t kTrajectoryCapacity = 1 << 16;
constexpr const char* kCameraLostHud = "camera lost: IMU orientation, walls kept";
constexpr const char* kImuLostHud = "IMU lost: 3-D wall search, no gyro prior";

class TrackingModule {
 public:
  TrackingModule(const RigCalibration& rig, const TrackingOptions& tracking,
                 const ApplianceOptions& options, PipelineSink& pipeline, Wakeup& wakeup,
                 Seqlock<PoseSnapshot>& pose, LiveView* view, Reconstruction* sync_reconstruction)
      : options_(options),
        pipeline_(pipeline),
        wakeup_(wakeup),
        pose_(pose),
        view_(view),
        sync_reconstruction_(sync_reconstruction),
        system_(rig, tracking),
        T_rect_body_(system_.tracker().T_body_rect().inverse()),
        R_body_imu_(rig.imu.T_body_imu.linear()),
        frame_period_ns_(frame_period_of(rig.cams[0])) {
    filter_ = std::make_unique<dsp::AttitudeFilter>(attitude_config_for(rig.imu));
    camera_timeout_ns_ = options.camera_timeout_ns > 0
                             ? options.camera_timeout_ns
                             : std::max<DurationNs>(4 * frame_period_ns_, 200 * kNsPerMs);
    trajectory_.reserve(kTrajectoryCapacity);
    events_.reserve(256);
  }

  /// The thread's body.
  void run(const std::atomic<bool>& stop, std::atomic<std::uint64_t>* allocations) {
    tl_allocation_counter = allocations;
    StereoFrame frame;
    while (!stop.load(std::memory_order_acquire)) {
      wakeup_.wait_for(10 * kNsPerMs);
      heartbeat_ns_.store(monotonic_now_ns(), std::memory_order_relaxed);
      wakeups_.fetch_add(1, std::memory_order_relaxed);
      if (reset_requested_.exchange(false)) do_reset();
      // Frames first, each after the IMU samples up to its time (they arrived before it);
      // then the samples after the newest frame. A tracker that fell behind thus never reads
      // the IMU running ahead of a frame still waiting as a lost camera.
      while (pipeline_.take_frame(frame)) {
        drain_imu(frame.t_ns);
        on_frame(frame);
        frame = StereoFrame{};  // give the buffers back now
        pipeline_.frame_done();
      }
      drain_imu(std::numeric_limits<TimeNs>::max());
    }
    tl_allocation_counter = nullptr;
  }

  void request_reset() {
    reset_requested_.store(true);
    wakeup_.notify();
  }

  /// After the thread stopped: stops mapping (global adjustment) and returns the final map.
  MapPtr finish() { return system_.finish(); }

  TrackingAndMapping& system() { return system_; }
  [[nodiscard]] TimeNs heartbeat_ns() const {
    return heartbeat_ns_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint64_t wakeups() const { return wakeups_.load(std::memory_order_relaxed); }
  [[nodiscard]] std::uint64_t misses() const { return misses_.load(std::memory_order_relaxed); }
  [[nodiscard]] const LatencyHistogram& queue_latency() const { return queue_; }
  [[nodiscard]] const LatencyHistogram& track_time() const { return track_; }
  [[nodiscard]] const LatencyHistogram& imu_latency() const { return imu_latency_; }
  [[nodiscard]] DurationNs frame_period_ns() const { return frame_period_ns_; }
  // Read after the thread stopped.
  [[nodiscard]] const std::vector<PoseRecord>& trajectory() const { return trajectory_; }
  [[nodiscard]] const DegradedCounters& degraded() const { return degraded_; }
  [[nodiscard]] const std::vector<std::string>& events() const { return events_; }
  [[nodiscard]] std::uint64_t tracked() const { return tracked_; }

 private:
  void event(TimeNs t_ns, const char* what) {
    char line[200];
    std::snprintf(line, sizeof line, "t=%.3f s: %s", t0_ns_ >= 0 ? ns_to_s(t_ns - t0_ns_) : 0.0,
                  what);
    // Transitions are rare and logged once each; the strings are the only allocation here.
    const AllocationPause pause;
    events_.emplace_back(line);
    if (options_.log) options_.log(line);
  }

  /// Allocation accounting pauses for the rare logged event (not the fixed-rate path).
  struct AllocationPause {
    AllocationPause() : saved(tl_allocation_counter) { tl_allocation_counter = nullptr; }
    ~AllocationPause() { tl_allocation_counter = saved; }
    AllocationPause(const AllocationPause&) = delete;
    AllocationPause& operator=(const AllocationPause&) = delete;
    std::atomic<std::uint64_t>* saved;
  };

  void drain_imu(TimeNs until_ns) {
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

  void on_imu(const ImuSample& s) {
    if (t0_ns_ < 0) t0_ns_ = s.t_ns;
    if (s.publish_t_ns > 0) imu_latency_.record(monotonic_now_ns() - s.publish_t_ns);
    system_.on_imu(s);
    filter_->update(s);
    last_imu_t_ns_ = s.t_ns;
    imu_seen_ = true;
    if (imu_lost_) {
      imu_lost_ = false;
      ++degraded_.imu_recovered;
      event(s.t_ns, "IMU back: gravity-aligned walls and gyro prior again");
    }
    if (last_frame_t_ns_ < 0) return;
    // The camera is alive while frames arrive, tracked or not: in real time the newest
    // delivered frame counts too (overwritten while tracking was busy). In lock step every
    // frame is tracked in order, so the tracked one alone decides (repeatable).
    const TimeNs last_seen_t_ns = options_.deterministic
                                      ? last_frame_t_ns_
                                      : std::max(last_frame_t_ns_, pipeline_.last_delivered_t_ns());
    if (!camera_lost_ && s.t_ns - last_seen_t_ns > camera_timeout_ns_) {
      camera_lost_ = true;
      ++degraded_.camera_lost;
      event(s.t_ns, "camera lost: IMU-only orientation, last wall model kept");
      R_world_body_at_loss_ = last_T_world_body_.linear();
      q_world_imu_at_loss_ = q_world_imu_last_frame_;
      last_imu_only_t_ns_ = -1;
    }
    if (camera_lost_ && filter_->initialized() &&
        (last_imu_only_t_ns_ < 0 || s.t_ns - last_imu_only_t_ns_ >= frame_period_ns_)) {
      publish_imu_only(s.t_ns);
    }
  }

  /// Camera lost: the last visual pose turned by the IMU's rotation since, position held.
  void publish_imu_only(TimeNs t_ns) {
    last_imu_only_t_ns_ = t_ns;
    const Eigen::Matrix3d R_imu0_imu =
        (q_world_imu_at_loss_.conjugate() * filter_->q_world_imu()).toRotationMatrix();
    SE3d T = last_T_world_body_;
    T.linear() = R_world_body_at_loss_ * R_body_imu_ * R_imu0_imu * R_body_imu_.transpose();
    const std::optional<Eigen::Vector3d> down = gravity_in_world(T);
    pose_.store(make_pose_snapshot(t_ns, T, dsp::TrackingState::kTracking, down, epoch_, true));
    ++degraded_.imu_only_poses;
    if (view_ != nullptr && !last_frame_.left.image.empty()) {
      ViewPost post;
      post.frame = last_frame_;
      post.capture_t_ns = monotonic_now_ns();
      post.T_world_body = T;
      post.state = dsp::TrackingState::kTracking;
      post.degraded = kCameraLostHud;
      view_->post(std::move(post));
    }
  }

  std::optional<Eigen::Vector3d> gravity_in_world(const SE3d& T_world_body) const {
    if (imu_lost_ || !filter_->initialized()) return std::nullopt;
    return (T_world_body.linear() * R_body_imu_ * filter_->gravity_dir_imu()).normalized();
  }

  void on_frame(const StereoFrame& f) {
    if (t0_ns_ < 0) t0_ns_ = f.t_ns;
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
    if (r.rejected != nullptr) return;
    ++tracked_;
    last_frame_t_ns_ = f.t_ns;
    last_frame_ = f;
    const SE3d T_world_body = r.T_world_cam * T_rect_body_;
    if (r.state == dsp::TrackingState::kTracking) {
      last_T_world_body_ = T_world_body;
      if (filter_->initialized()) q_world_imu_last_frame_ = filter_->q_world_imu();
    }
    if (trajectory_.size() < trajectory_.capacity()) {
      trajectory_.push_back({f.t_ns, T_world_body, r.state});
    }
    const std::optional<Eigen::Vector3d> down = gravity_in_world(T_world_body);
    pose_.store(make_pose_snapshot(f.t_ns, T_world_body, r.state, down, epoch_, false));
    if (view_ != nullptr) {
      ViewPost post;
      post.frame = f;
      post.capture_t_ns = f.left.publish_t_ns;
      post.T_world_body = T_world_body;
      post.state = r.state;
      post.degraded = imu_lost_ ? kImuLostHud : nullptr;
      view_->post(std::move(post));
    }
    if (sync_reconstruction_ != nullptr && r.keyframe) {
      // Deterministic mode: the walls at fixed points of the stream (after key-frames).
      const AllocationPause pause;
      if (const MapPtr map = system_.latest_map()) {
        sync_reconstruction_->maybe_run(*map, down, epoch_, false);
      }
    }
  }

  void do_reset() {
    const AllocationPause pause;  // a reset rebuilds the mapper: allowed to allocate
    system_.reset();
    ++epoch_;
    ++degraded_.resets;
    last_frame_ = StereoFrame{};
    event(last_frame_t_ns_ >= 0 ? last_frame_t_ns_ : 0, "reset: tracking and map start again");
  }

  const ApplianceOptions& options_;
  PipelineSink& pipeline_;
  Wakeup& wakeup_;
  Seqlock<PoseSnapshot>& pose_;
  LiveView* view_;
  Reconstruction* sync_reconstruction_;
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

  std::atomic<TimeNs> heartbeat_ns_{0};
  std::atomic<std::uint64_t> wakeups_{0};
  std::atomic<std::uint64_t> misses_{0};
  std::uint64_t tracked_ = 0;
  LatencyHistogram queue_, track_, imu_latency_;
  std::vector<PoseRecord> trajectory_;
  DegradedCounters degraded_;
  std::vector<std::string> events_;
};

// ---------------------------------------------------------------------------------------------
// Sources behind one interface: replay (one thread) or the live drivers (capture + imu).

class SourceModule {
 public:
  virtual ~SourceModule() = default;
  virtual void start(source::SensorSink& sink, drivers::ImuSampleSink& imu_sink, bool realtime,
                     const std::atomic<bool>& stop) = 0;
  [[nodiscard]] virtual bool finished() const = 0;
  /// Phase two: waits up to `timeout_ns` for the threads to end; false if one is stuck.
  virtual bool join_within(DurationNs timeout_ns) = 0;
  [[nodiscard]] virtual std::string describe() const = 0;
  [[nodiscard]] virtual std::vector<const RtThread*> threads() const = 0;
  /// The error a source thread ended with (empty if none).
  [[nodiscard]] virtual std::string error() const = 0;
};

bool wait_flag(const std::atomic<bool>& flag, DurationNs timeout_ns) {
  const TimeNs until = monotonic_now_ns() + timeout_ns;
  while (!flag.load(std::memory_order_acquire)) {
    if (monotonic_now_ns() >= until) return false;
    const timespec ts{0, 5 * kNsPerMs};
    nanosleep(&ts, nullptr);
  }
  return true;
}

class ReplayModule final : public SourceModule {
 public:
  ReplayModule(const recording::EurocRecording& rec, const source::ReplayOptions& replay, int loops,
               std::vector<FaultSpec> faults)
      : rec_(rec), replay_(replay), loops_(loops), faults_(std::move(faults)) {}
  void start(source::SensorSink& sink, drivers::ImuSampleSink& /*imu_sink*/, bool realtime,
             const std::atomic<bool>& stop) override {
    faults_sink_ = std::make_unique<FaultSink>(sink, faults_);
    const auto& frames = rec_.cams[0].frames;
    const TimeNs imu_end_ns =
        frames.empty() ? std::numeric_limits<TimeNs>::max() : frames.back().t_ns + period_ns();
    shift_ = std::make_unique<LoopShift>(*faults_sink_, imu_end_ns);
    thread_ = std::make_unique<RtThread>(spec_of("replay", realtime), [this, &stop, imu_end_ns] {
      const DurationNs period = period_ns();
      DurationNs offset = 0;
      for (int loop = 0; (loops_ == 0 || loop < loops_) && !stop.load(); ++loop) {
        shift_->set_offset(offset);
        source::ReplaySource source(rec_, replay_);
        const source::ReplayStats s = source.run(*shift_, stop);
        accumulate(s);
        if (s.pairs_delivered == 0 && s.imu_samples == 0) break;
        offset += (std::min(s.last_t_ns, imu_end_ns) - s.first_t_ns) + period;
      }
      done_.store(true, std::memory_order_release);
    });
  }
  [[nodiscard]] bool finished() const override { return done_.load(std::memory_order_acquire); }
  bool join_within(DurationNs timeout_ns) override {
    if (!thread_) return true;
    if (!wait_flag(done_, timeout_ns) && !thread_->failed()) return false;
    thread_->join();
    return true;
  }
  [[nodiscard]] std::string describe() const override {
    char rate[32] = "full speed";
    if (replay_.rate > 0) std::snprintf(rate, sizeof rate, "%gx", replay_.rate);
    char loops[32] = "";
    if (loops_ == 0) std::snprintf(loops, sizeof loops, ", looped");
    if (loops_ > 1) std::snprintf(loops, sizeof loops, ", %d loops", loops_);
    char buf[600];
    std::snprintf(buf, sizeof buf, "replay of %s at %s%s", rec_.mav0.parent_path().string().c_str(),
                  rate, loops);
    return buf;
  }
  [[nodiscard]] std::vector<const RtThread*> threads() const override { return {thread_.get()}; }
  [[nodiscard]] std::string error() const override {
    return thread_ && thread_->failed() ? thread_->error() : std::string();
  }
  [[nodiscard]] source::ReplayStats stats() const {
    const std::lock_guard lock(mutex_);
    return stats_;
  }
  [[nodiscard]] int loops_played() const {
    const std::lock_guard lock(mutex_);
    return loops_played_;
  }
  [[nodiscard]] std::uint64_t injected() const {
    return faults_sink_ ? faults_sink_->injected() : 0;
  }

 private:
  DurationNs period_ns() const { return frame_period_of(rec_.cams[0].calib); }
  void accumulate(const source::ReplayStats& s) {
    const std::lock_guard lock(mutex_);
    if (loops_played_ == 0) {
      stats_ = s;
    } else {
      stats_.imu_samples += s.imu_samples;
      stats_.frames[0] += s.frames[0];
      stats_.frames[1] += s.frames[1];
      stats_.pairs_delivered += s.pairs_delivered;
      stats_.pairs_skipped += s.pairs_skipped;
      stats_.wall_time_ns += s.wall_time_ns;
      stats_.max_lateness_ns = std::max(stats_.max_lateness_ns, s.max_lateness_ns);
      stats_.stopped = s.stopped;
    }
    ++loops_played_;
  }

  const recording::EurocRecording& rec_;
  source::ReplayOptions replay_;
  int loops_;
  std::vector<FaultSpec> faults_;
  std::unique_ptr<FaultSink> faults_sink_;
  std::unique_ptr<LoopShift> shift_;
  std::unique_ptr<RtThread> thread_;
  std::atomic<bool> done_{false};
  mutable std::mutex mutex_;  // stats: written once per loop, read by the supervisor
  source::ReplayStats stats_;
  int loops_played_ = 0;
};

class LiveModule final : public SourceModule {
 public:
  explicit LiveModule(const BoardConfig& board) : board_(board) {}
  void start(source::SensorSink& sink, drivers::ImuSampleSink& imu_sink, bool realtime,
             const std::atomic<bool>& stop) override {
    // Devices open here, before any thread: a missing one is an error at start.
    cameras_ = std::make_unique<LiveStereo>(board_, sink);
    if (board_.imu.driver != "none") imu_ = std::make_unique<LiveImu>(board_, imu_sink);
    capture_ = std::make_unique<RtThread>(spec_of("capture", realtime), [this, &stop] {
      cameras_->run(std::numeric_limits<TimeNs>::max(), stop);
      capture_done_.store(true, std::memory_order_release);
    });
    if (imu_) {
      imu_thread_ = std::make_unique<RtThread>(spec_of("imu", realtime), [this, &stop] {
        imu_->run(std::numeric_limits<TimeNs>::max(), stop);
        imu_done_.store(true, std::memory_order_release);
      });
    } else {
      imu_done_.store(true);
    }
  }
  [[nodiscard]] bool finished() const override { return capture_done_.load() && imu_done_.load(); }
  bool join_within(DurationNs timeout_ns) override {
    const TimeNs until = monotonic_now_ns() + timeout_ns;
    if (capture_ && !wait_flag(capture_done_, until - monotonic_now_ns()) && !capture_->failed())
      return false;
    if (imu_thread_ && !wait_flag(imu_done_, std::max<DurationNs>(0, until - monotonic_now_ns())) &&
        !imu_thread_->failed())
      return false;
    if (capture_) capture_->join();
    if (imu_thread_) imu_thread_->join();
    return true;
  }
  [[nodiscard]] std::string describe() const override {
    return cameras_ ? cameras_->description() + (imu_ ? "; " + imu_->description() : "; no IMU")
                    : "live sensors";
  }
  [[nodiscard]] std::vector<const RtThread*> threads() const override {
    std::vector<const RtThread*> t{capture_.get()};
    if (imu_thread_) t.push_back(imu_thread_.get());
    return t;
  }
  [[nodiscard]] std::string error() const override {
    if (capture_ && capture_->failed()) return capture_->error();
    if (imu_thread_ && imu_thread_->failed()) return imu_thread_->error();
    return {};
  }

 private:
  const BoardConfig& board_;
  std::unique_ptr<LiveStereo> cameras_;
  std::unique_ptr<LiveImu> imu_;
  std::unique_ptr<RtThread> capture_, imu_thread_;
  std::atomic<bool> capture_done_{false}, imu_done_{false};
};

// ---------------------------------------------------------------------------------------------
// Inputs: evdev keys and GPIO buttons (reset, exit). Polled by the supervisor without waiting.

class Inputs {
 public:
  Inputs(const BoardConfig& board, const ApplianceOptions& options) {
    if (!options.input_keys.empty())
      keys_ = std::make_unique<drivers::EvdevKeys>(options.input_keys);
    constexpr DurationNs kDebounceNs = 20 * kNsPerMs;
    if (board.reset_button) {
      reset_ = std::make_unique<drivers::GpioButton>(gpio_spec(*board.reset_button), "wallar-reset",
                                                     kDebounceNs);
    }
    if (board.exit_button) {
      exit_ = std::make_unique<drivers::GpioButton>(gpio_spec(*board.exit_button), "wallar-exit",
                                                    kDebounceNs);
    }
  }
  drivers::InputAction poll(TimeNs now_ns) {
    if (keys_ && !keys_->lost()) {
      const drivers::InputAction a = keys_->poll(0);
      if (a != drivers::InputAction::kNone) return a;
    }
    if (exit_) {
      if (const auto pressed = exit_->service(0, now_ns); pressed && *pressed)
        return drivers::InputAction::kExit;
    }
    if (reset_) {
      if (const auto pressed = reset_->service(0, now_ns); pressed && *pressed)
        return drivers::InputAction::kReset;
    }
    return drivers::InputAction::kNone;
  }
  [[nodiscard]] std::string describe() const {
    std::string s;
    if (keys_) s += "keys";
    if (reset_) s += s.empty() ? "reset button" : ", reset button";
    if (exit_) s += s.empty() ? "exit button" : ", exit button";
    return s.empty() ? "none" : s;
  }

 private:
  static drivers::GpioLineSpec gpio_spec(const GpioLine& line) {
    drivers::GpioLineSpec spec;
    spec.chip = line.chip;
    spec.line = static_cast<unsigned>(line.line);
    spec.active_low = line.active_low;
    return spec;
  }
  std::unique_ptr<drivers::EvdevKeys> keys_;
  std::unique_ptr<drivers::GpioButton> reset_, exit_;
};

// ---------------------------------------------------------------------------------------------
// Stats rows.

std::string policy_of(const RtThread& t) {
  const ThreadPlacement& p = t.placement();
  return p.fifo ? "FIFO " + std::to_string(p.priority) : std::string("OTHER");
}

ThreadRow row_of(const RtThread& t, DurationNs run_ns, std::uint64_t wakeups, std::uint64_t misses,
                 const std::atomic<std::uint64_t>* allocations) {
  ThreadRow r;
  r.name = t.spec().name;
  r.policy = policy_of(t);
  r.cpu = t.placement().cpu;
  r.cpu_s = ns_to_s(t.cpu_time_ns());
  r.cpu_percent =
      run_ns > 0 ? 100.0 * static_cast<double>(t.cpu_time_ns()) / static_cast<double>(run_ns) : 0.0;
  r.wakeups = wakeups;
  r.misses = misses;
  if (allocations != nullptr && g_allocations_counted) r.allocations = allocations->load();
  r.note = t.placement().fallback.empty() ? table_entry(t.spec().name.c_str()).role
                                          : t.placement().fallback;
  return r;
}

StageRow stage(const char* name, const LatencyHistogram& h, DurationNs deadline_ns,
               std::uint64_t misses) {
  StageRow s;
  s.name = name;
  s.latency = h.summary();
  s.deadline_ns = deadline_ns;
  s.misses = misses;
  return s;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

FaultSpec parse_fault(const std::string& text) {
  auto fail = [&](const char* why) -> FaultSpec {
    throw InputError("--fault '" + text + "': " + why +
                     " (expected camera-stall@T+D, imu-unplug@T+D or corrupt-frame@T, seconds)");
  };
  const std::size_t at = text.find('@');
  if (at == std::string::npos) return fail("no '@'");
  const std::string kind = text.substr(0, at);
  FaultSpec f;
  if (kind == "camera-stall") {
    f.kind = FaultSpec::Kind::kCameraStall;
  } else if (kind == "imu-unplug") {
    f.kind = FaultSpec::Kind::kImuUnplug;
  } else if (kind == "corrupt-frame") {
    f.kind = FaultSpec::Kind::kCorruptFrame;
  } else {
    return fail("unknown fault");
  }
  const std::string rest = text.substr(at + 1);
  const std::size_t plus = rest.find('+');
  auto number = [&](const std::string& s, double& out) {
    const char* end = s.data() + s.size();
    const auto [ptr, ec] = std::from_chars(s.data(), end, out);
    if (ec != std::errc() || ptr != end || !std::isfinite(out) || out < 0.0) fail("bad number");
  };
  number(rest.substr(0, plus), f.at_s);
  if (f.kind == FaultSpec::Kind::kCorruptFrame) {
    if (plus != std::string::npos) fail("corrupt-frame takes no duration");
  } else {
    if (plus == std::string::npos) fail("missing '+DURATION'");
    number(rest.substr(plus + 1), f.duration_s);
    if (f.duration_s <= 0.0) fail("duration must be > 0");
  }
  return f;
}

std::string to_string(const FaultSpec& fault) {
  char buf[96];
  switch (fault.kind) {
    case FaultSpec::Kind::kCameraStall:
      std::snprintf(buf, sizeof buf, "camera-stall@%g+%g", fault.at_s, fault.duration_s);
      break;
    case FaultSpec::Kind::kImuUnplug:
      std::snprintf(buf, sizeof buf, "imu-unplug@%g+%g", fault.at_s, fault.duration_s);
      break;
    case FaultSpec::Kind::kCorruptFrame:
      std::snprintf(buf, sizeof buf, "corrupt-frame@%g", fault.at_s);
      break;
  }
  return buf;
}

std::string format_stats_table(const std::vector<ThreadRow>& threads,
                               const std::vector<StageRow>& stages) {
  std::string out;
  char line[320];
  std::snprintf(line, sizeof line, "%-12s %-9s %4s %9s %6s %9s %7s %7s  %s\n", "thread", "policy",
                "cpu", "cpu_s", "cpu%", "wakeups", "misses", "allocs", "role");
  out += line;
  for (const ThreadRow& t : threads) {
    const std::string allocs = t.allocations ? std::to_string(*t.allocations) : "-";
    std::snprintf(line, sizeof line, "%-12s %-9s %4s %9.3f %6.1f %9llu %7llu %7s  %s\n",
                  t.name.c_str(), t.policy.c_str(),
                  t.cpu < 0 ? "any" : std::to_string(t.cpu).c_str(), t.cpu_s, t.cpu_percent,
                  static_cast<unsigned long long>(t.wakeups),
                  static_cast<unsigned long long>(t.misses), allocs.c_str(), t.note.c_str());
    out += line;
  }
  std::snprintf(line, sizeof line, "\n%-22s %8s %9s %9s %9s %9s %8s %7s\n", "stage", "count",
                "p50_ms", "p99_ms", "max_ms", "mean_ms", "dl_ms", "misses");
  out += line;
  for (const StageRow& s : stages) {
    const std::string deadline =
        s.deadline_ns > 0 ? std::to_string(static_cast<double>(s.deadline_ns) * 1e-6).substr(0, 6)
                          : "-";
    std::snprintf(line, sizeof line, "%-22s %8llu %9.2f %9.2f %9.2f %9.2f %8s %7llu\n",
                  s.name.c_str(), static_cast<unsigned long long>(s.latency.count),
                  s.latency.p50_ms, s.latency.p99_ms, s.latency.max_ms, s.latency.mean_ms,
                  deadline.c_str(), static_cast<unsigned long long>(s.misses));
    out += line;
  }
  return out;
}

ApplianceReport run_appliance(const BoardConfig& board, const ApplianceOptions& options_in,
                              const std::atomic<bool>& stop, std::atomic<bool>* stats_request) {
  ApplianceOptions options = options_in;
  if (!options.log) options.log = default_log;
  const bool replay = board.source == BoardConfig::Source::kReplay;
  if (!replay && (options.deterministic || !options.faults.empty() || options.loops != 1)) {
    throw InputError(board.file.string() +
                     ": --deterministic, --fault and --loop need a replay board");
  }
  ApplianceReport report;
  const TimeNs t_start = monotonic_now_ns();

  // Everything that can fail on bad input or a missing device, before any thread starts.
  std::optional<recording::EurocRecording> rec;
  RigCalibration rig;
  if (replay) {
    rec = recording::read_euroc(board.replay.recording);
    rig = rec->rig();
  } else {
    if (!board.calibration) {
      throw InputError(board.file.string() +
                       ": a live board needs calibration: (the rig's "
                       "intrinsics and extrinsics) to track");
    }
    rig = recording::read_rig_calibration(*board.calibration);
  }
  // Fixed priorities pace real time; a fast replay runs every thread as SCHED_OTHER.
  const bool realtime = options.realtime && !(replay && options.replay.rate <= 0.0);
  if (realtime) {
    const MemoryLock lock = lock_memory();
    report.memory_locked = lock.locked;
    if (!lock.locked) options.log(lock.warning);
  }
  Inputs inputs(board, options);
  SystemdNotifier notifier;

  // Channels.
  std::atomic<bool> stop_modules{false};
  Wakeup tracking_wakeup;
  PipelineSink pipeline(tracking_wakeup, stop_modules, options.deterministic);
  Seqlock<PoseSnapshot> pose;
  TripleBuffer<WallModel> walls_channel;
  TripleBuffer<MapPtr> map_channel;

  // Modules.
  TrackingOptions tracking = tracking_options(board.tracking);
  if (options.deterministic) tracking.mapping_thread = false;
  tracking.mapping_thread_spec = spec_of("mapping", realtime);
  tracking.map_channel = &map_channel;
  Reconstruction reconstruction(options, static_cast<std::size_t>(board.tracking.max_map_points),
                                walls_channel);
  std::unique_ptr<LiveView> view;
  if (options.view) {
    HeadsetViewOptions vo = view_options(board.display);
    vo.png_dir = options.png_dir;
    vo.png_every = options.png_dir.empty() ? 0 : std::max(1, options.png_every);
    view = std::make_unique<LiveView>(rig, vo, WallModel{}, rig.cams[0].rate_hz, &walls_channel,
                                      spec_of("render", realtime));
    report.display = view->display();
  }
  TrackingModule tracker(rig, tracking, options, pipeline, tracking_wakeup, pose, view.get(),
                         options.deterministic ? &reconstruction : nullptr);
  std::unique_ptr<SourceModule> source;
  ReplayModule* replay_module = nullptr;
  if (replay) {
    source::ReplayOptions replay_options = options.replay;
    auto r = std::make_unique<ReplayModule>(*rec, replay_options, options.loops, options.faults);
    replay_module = r.get();
    source = std::move(r);
  } else {
    source = std::make_unique<LiveModule>(board);
  }

  // Threads, consumers first so nothing produced is lost.
  std::atomic<std::uint64_t> tracking_allocs{0}, reconstruct_allocs{0}, supervisor_allocs{0};
  RtThread tracking_thread(spec_of("tracking", realtime),
                           [&] { tracker.run(stop_modules, &tracking_allocs); });
  std::atomic<std::uint64_t> reconstruct_wakeups{0};
  std::unique_ptr<PeriodicTimer> reconstruct_timer;
  std::unique_ptr<RtThread> reconstruct_thread;
  if (!options.deterministic) {
    reconstruct_timer = std::make_unique<PeriodicTimer>(options.reconstruct_period_ns);
    reconstruct_thread = std::make_unique<RtThread>(spec_of("reconstruct", realtime), [&] {
      // Counted, not required to be zero: the wall search builds its result (a background
      // module like mapping; tracking never waits for it).
      tl_allocation_counter = &reconstruct_allocs;
      MapPtr map;
      while (!stop_modules.load(std::memory_order_acquire)) {
        reconstruct_timer->wait();
        reconstruct_wakeups.fetch_add(1, std::memory_order_relaxed);
        if (map_channel.refresh()) map = map_channel.front();
        if (!map) continue;
        const PoseSnapshot p = pose.load();
        reconstruction.maybe_run(*map, down_of(p), p.epoch, false);
      }
      tl_allocation_counter = nullptr;
    });
  }
  try {
    source->start(pipeline, pipeline, realtime, stop_modules);  // live: opens the devices
  } catch (...) {
    // The consumers already run: stop them before unwinding joins them.
    stop_modules.store(true, std::memory_order_release);
    tracking_wakeup.notify();
    throw;
  }
  report.source = source->describe();
  {
    char line[700];
    std::snprintf(line, sizeof line, "board %s: %s; display %s; inputs %s%s", board.name.c_str(),
                  report.source.c_str(), view ? report.display.c_str() : "none",
                  inputs.describe().c_str(), options.deterministic ? "; deterministic" : "");
    options.log(line);
  }
  {
    // Placement fallbacks (no SCHED_FIFO, a missing CPU), said once per thread at start.
    std::vector<const RtThread*> started = source->threads();
    started.push_back(&tracking_thread);
    started.push_back(reconstruct_thread.get());
    started.push_back(tracker.system().mapping_thread());
    if (view) started.push_back(view->thread());
    for (const RtThread* t : started) {
      if (t != nullptr && !t->placement().fallback.empty()) {
        options.log("thread " + t->spec().name + ": " + t->placement().fallback);
      }
    }
  }
  notifier.ready();
  notifier.status("running");

  // Supervisor.
  // `final`: after the tracking thread stopped (the mapping thread may be replaced by a reset
  // while it runs, so only the final table lists it).
  auto live_rows = [&](DurationNs run_ns, bool final) {
    std::vector<ThreadRow> threads;
    for (const RtThread* t : source->threads()) {
      if (t != nullptr) threads.push_back(row_of(*t, run_ns, 0, 0, nullptr));
    }
    threads.push_back(
        row_of(tracking_thread, run_ns, tracker.wakeups(), tracker.misses(), &tracking_allocs));
    if (const RtThread* m = final ? tracker.system().mapping_thread() : nullptr) {
      threads.push_back(row_of(*m, run_ns, 0, 0, nullptr));
    }
    if (reconstruct_thread) {
      threads.push_back(row_of(*reconstruct_thread, run_ns, reconstruct_wakeups.load(),
                               reconstruct_timer->misses(), &reconstruct_allocs));
    }
    if (view) {
      if (const RtThread* r = view->thread()) {
        threads.push_back(row_of(*r, run_ns, view->attempts(), view->misses(), nullptr));
      }
    }
    return threads;
  };
  const DurationNs frame_period = tracker.frame_period_ns();
  auto stage_rows = [&] {
    std::vector<StageRow> stages;
    stages.push_back(stage("imu -> filter", tracker.imu_latency(), 0, 0));
    stages.push_back(stage("capture -> tracking", tracker.queue_latency(), 0, 0));
    stages.push_back(stage("tracking", tracker.track_time(), frame_period, tracker.misses()));
    stages.push_back(stage("reconstruction", reconstruction.time(), 0, 0));
    if (view) {
      stages.push_back(stage("render", view->render_time(), frame_period, view->misses()));
      stages.push_back(stage("camera -> display", view->latency(), 0, 0));
    }
    return stages;
  };

  report.rss_kb.reserve(1 << 16);
  TimeNs next_rss_ns = t_start;
  PeriodicTimer supervisor(options.supervisor_period_ns);
  std::uint64_t supervisor_wakeups = 0;
  bool tracking_stalled = false;
  std::string module_error;
  tl_allocation_counter = &supervisor_allocs;
  for (;;) {
    supervisor.wait();
    ++supervisor_wakeups;
    const TimeNs now = monotonic_now_ns();
    if (now >= next_rss_ns && report.rss_kb.size() < report.rss_kb.capacity()) {
      report.rss_kb.push_back(current_rss_kb());
      next_rss_ns = now + options.rss_sample_period_ns;
    }
    if (stop.load(std::memory_order_acquire)) {
      report.stop_reason = "signal";
      report.interrupted = true;
      break;
    }
    if (options.max_duration_ns > 0 && now - t_start >= options.max_duration_ns) {
      report.stop_reason = "time limit";
      break;
    }
    if (tracking_thread.failed()) {
      module_error = "tracking: " + tracking_thread.error();
      break;
    }
    if (const std::string e = source->error(); !e.empty()) {
      module_error = e;
      break;
    }
    if (source->finished() && pipeline.drained()) {
      report.stop_reason = replay ? "end of replay" : "sensors stopped";
      break;
    }
    switch (inputs.poll(now)) {
      case drivers::InputAction::kExit:
        report.stop_reason = "exit input";
        report.interrupted = true;
        break;
      case drivers::InputAction::kReset:
        tracker.request_reset();
        [[fallthrough]];
      case drivers::InputAction::kNone:
        break;
    }
    if (report.interrupted) break;
    if (stats_request != nullptr && stats_request->exchange(false)) {
      tl_allocation_counter = nullptr;  // a request, not the fixed-rate path
      const std::string table = format_stats_table(live_rows(now - t_start, false), stage_rows());
      std::fprintf(stderr, "%s", table.c_str());
      tl_allocation_counter = &supervisor_allocs;
    }
    // Health: tracking wakes at least every 10 ms; two seconds of silence is a hang.
    const bool stalled = now - tracker.heartbeat_ns() > 2 * kNsPerS;
    if (stalled != tracking_stalled) {
      tracking_stalled = stalled;
      tl_allocation_counter = nullptr;
      options.log(stalled ? "tracking thread stalled (no heartbeat for 2 s): watchdog withheld"
                          : "tracking thread alive again");
      tl_allocation_counter = &supervisor_allocs;
    }
    if (!stalled && notifier.watchdog_due(now)) notifier.watchdog(now);
  }
  tl_allocation_counter = nullptr;
  notifier.stopping();

  // Phase one: break the links. Producers stop producing, waits are released.
  stop_modules.store(true, std::memory_order_release);
  tracking_wakeup.notify();
  pipeline.release_producers();
  // Phase two: join and destroy, source first (it may be inside a device call).
  if (!source->join_within(3 * kNsPerS)) {
    options.log("the source did not stop within 3 s (stuck in a device call): exiting without it");
    std::fflush(nullptr);
    std::_Exit(1);
  }
  tracking_thread.join();
  if (reconstruct_thread) reconstruct_thread->join();
  const DurationNs run_ns = monotonic_now_ns() - t_start;
  report.threads = live_rows(run_ns, true);
  ThreadRow sup;
  sup.name = "supervisor";
  sup.policy = "OTHER";
  sup.wakeups = supervisor_wakeups;
  sup.misses = supervisor.misses();
  if (g_allocations_counted) sup.allocations = supervisor_allocs.load();
  sup.note = table_entry("supervisor").role;
  report.threads.push_back(sup);
  // The final map (mapping stopped after a global adjustment) and its walls.
  const MapPtr final_map = tracker.finish();
  if (final_map) {
    report.map = final_map;
    report.map_points = final_map->points.size();
    report.map_keyframes = final_map->keyframe_centres.size();
    const PoseSnapshot p = pose.load();
    reconstruction.maybe_run(*final_map, down_of(p), p.epoch, true);
  }
  if (view) report.view = view->stop();
  report.stages = stage_rows();
  LatencyHistogram mapping;
  for (const std::int64_t ns : tracker.system().mapping_times_ns()) mapping.record(ns);
  report.stages.insert(report.stages.begin() + 3, stage("mapping (local BA)", mapping, 0, 0));
  if (!module_error.empty()) throw std::runtime_error(module_error);

  report.room = reconstruction.result();
  report.room_gravity = reconstruction.gravity();
  report.reconstructions = reconstruction.runs();
  report.tracking = tracker.system().counters();
  report.degraded = tracker.degraded();
  report.trajectory = tracker.trajectory();
  report.events = tracker.events();
  report.imu_samples = pipeline.imu_in();
  report.imu_dropped = pipeline.imu_dropped();
  report.frames_in = pipeline.frames_in();
  report.frames_overwritten = pipeline.frames_overwritten();
  report.frames_tracked = tracker.tracked();
  if (replay_module != nullptr) {
    report.replay = replay_module->stats();
    report.loops_played = replay_module->loops_played();
    report.degraded.faults_injected = replay_module->injected();
  }
  report.wall_time_ns = run_ns;
  report.max_rss_kb = max_rss_kb();
  return report;
}

}  // namespace wallar::firmware
