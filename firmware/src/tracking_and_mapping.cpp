// SPDX-License-Identifier: Apache-2.0
/// @file tracking_and_mapping.cpp
/// @brief The tracker on the caller's thread, the mapper on its own, rings between them.
#include "wallar/firmware/tracking_and_mapping.hpp"

#include <chrono>
#include <span>

#include "wallar/dsp/imu/gyro_integration.hpp"

namespace wallar::firmware {
namespace {
/// Key-frames queued for the mapper: when it falls this far behind the tracker makes no more
/// key-frames (it tracks on the map it has, counted) until the mapper catches up.
constexpr std::size_t kKeyframeSlots = 16;
constexpr std::size_t kCorrectionSlots = 4;
/// Key-frame poses one correction carries (the tracker keeps fewer records than this).
constexpr std::size_t kMaxCorrectedKeyframes = 4096;
}  // namespace

TrackingOptions tracking_options(const TrackingConfig& board) {
  TrackingOptions o;
  o.tracker.max_tracks = board.max_tracks;
  o.tracker.keyframe_points = board.keyframe_points;
  o.tracker.max_map_points = board.max_map_points;
  o.tracker.max_keyframes = board.max_keyframes;
  o.tracker.pyramid_levels = board.pyramid_levels;
  o.mapping_thread = board.mapping_thread;
  return o;
}

TrackingAndMapping::TrackingAndMapping(const RigCalibration& rig, const TrackingOptions& options,
                                       dsp::Tracker::Clock clock)
    : options_(options),
      tracker_(rig, options.tracker, clock),
      mapper_(std::make_unique<dsp::Mapper>(tracker_.intrinsics(), options.mapper)),
      intrinsics_(tracker_.intrinsics()),
      keyframes_(
          kKeyframeSlots,
          [&] {
            return KeyframeSlot{
                0, dsp::KeyframeMessage(static_cast<std::size_t>(options.tracker.max_tracks +
                                                                 options.tracker.keyframe_points),
                                        static_cast<std::size_t>(options.tracker.max_map_points))};
          }),
      corrections_(
          kCorrectionSlots,
          [&] {
            return CorrectionSlot{
                0, dsp::MapCorrection(static_cast<std::size_t>(options.tracker.max_map_points),
                                      kMaxCorrectedKeyframes)};
          }),
      lockstep_correction_(static_cast<std::size_t>(options.tracker.max_map_points),
                           kMaxCorrectedKeyframes),
      gyro_(static_cast<std::size_t>(std::max(16, options.imu_capacity))) {
  T_rect_imu_ = tracker_.T_body_rect().inverse() * rig.imu.T_body_imu;
  timeshift_cam_imu_ns_ = rig.imu.timeshift_cam_imu_ns;
  accel_bias_m_s2_ = rig.imu.accel_bias_m_s2;
  if (options_.mapping_thread) start_mapping();
}

void TrackingAndMapping::start_mapping() {
  stop_.store(false);
  thread_ = std::make_unique<RtThread>(options_.mapping_thread_spec, [this] { mapping_loop(); });
}

TrackingAndMapping::~TrackingAndMapping() {
  stop_.store(true);
  mapper_wakeup_.notify();
  if (thread_ && thread_->joinable()) thread_->join();
}

void TrackingAndMapping::reset() {
  tracker_.reset();
  last_frame_t_ns_ = -1;
  if (thread_ && thread_->joinable()) {
    // A new epoch, asked of the mapping thread without waiting for it (it may be in a bundle
    // adjustment for a while): it starts the new map when it next looks, and drops the old
    // epoch's key-frames; its corrections still queued or still coming are dropped here.
    ++epoch_;
    reset_epoch_.store(epoch_, std::memory_order_release);
    while (corrections_.front() != nullptr) corrections_.pop();
    mapper_wakeup_.notify();
    return;
  }
  lockstep_since_global_ = 0;
  new_map();
}

void TrackingAndMapping::new_map() {
  mapper_ = std::make_unique<dsp::Mapper>(intrinsics_, options_.mapper);
  {
    const std::lock_guard<std::mutex> lock(map_mutex_);
    map_.reset();
  }
  for (auto* channel : {options_.map_channel, options_.live_map_channel}) {
    if (channel == nullptr) continue;
    channel->back() = nullptr;
    channel->publish();
  }
}

void TrackingAndMapping::on_imu(const ImuSample& sample) {
  gyro_[gyro_head_] = sample;
  gyro_head_ = (gyro_head_ + 1) % gyro_.size();
  gyro_count_ = std::min(gyro_count_ + 1, gyro_.size());
}

dsp::RotationPrior TrackingAndMapping::gyro_prior(TimeNs t_ns) {
  dsp::RotationPrior prior;
  if (!options_.use_gyro || last_frame_t_ns_ < 0 || gyro_count_ < 2) return prior;
  // The ring as two time-ordered spans (older, newer).
  const std::size_t size = gyro_.size();
  const std::size_t first = (gyro_head_ + size - gyro_count_) % size;
  const std::span<const ImuSample> all(gyro_);
  const std::span<const ImuSample> older =
      first + gyro_count_ <= size ? all.subspan(first, gyro_count_) : all.subspan(first);
  const std::span<const ImuSample> newer =
      first + gyro_count_ <= size ? std::span<const ImuSample>() : all.first(gyro_head_);
  dsp::GyroIntegrationOptions gi;
  gi.timeshift_cam_imu_ns = timeshift_cam_imu_ns_;
  gi.accel_bias_m_s2 = accel_bias_m_s2_;
  const dsp::GyroDelta delta =
      dsp::integrate_gyro(older, newer, last_frame_t_ns_, t_ns, gyro_bias_rad_s_, gi);
  if (!delta.valid) return prior;
  // Into the rectified left camera: R_prev_cur(cam) = R_cam_imu R_prev_cur(imu) R_imu_cam.
  const Eigen::Quaterniond q_rect_imu(T_rect_imu_.linear());
  prior.q_prev_cur = (q_rect_imu * delta.q_start_end * q_rect_imu.conjugate()).normalized();
  prior.valid = true;
  prior.bias_corrected = gyro_bias_known_;
  prior.accel_valid = true;  // whether it is used: TrackerConfig::accel_prediction
  prior.dv_imu_m_s = delta.dv_m_s;
  prior.dp_imu_m = delta.dp_m;
  return prior;
}

void TrackingAndMapping::set_gyro_bias(const Eigen::Vector3d& bias_rad_s) {
  gyro_bias_rad_s_ = bias_rad_s;
  gyro_bias_known_ = true;
}

dsp::TrackResult TrackingAndMapping::on_stereo(const StereoFrame& frame) {
  // Corrections from the mapping thread first: the pose then starts from the adjusted map.
  if (options_.mapping_thread) {
    bool freed = false;
    while (CorrectionSlot* c = corrections_.front()) {
      if (c->epoch == epoch_) {  // not the map before a reset
        tracker_.apply(c->correction);
        ++counters_.corrections_applied;
      }
      corrections_.pop();
      freed = true;
    }
    if (freed) mapper_wakeup_.notify();  // it may wait for a free slot
  }
  const dsp::RotationPrior prior = gyro_prior(frame.t_ns);
  // A key-frame only when the mapper can take it: never one the map would not hear of.
  KeyframeSlot* slot = options_.mapping_thread ? keyframes_.producer_slot() : nullptr;
  tracker_.set_keyframes_allowed(!options_.mapping_thread || slot != nullptr);
  const dsp::TrackResult result =
      tracker_.track(frame.t_ns, frame.left.image, frame.right.image, prior);
  ++counters_.frames;
  counters_.stale_updates += static_cast<std::uint64_t>(result.stale_updates);
  if (result.rejected != nullptr) {
    ++counters_.rejected_frames;
    return result;
  }
  last_frame_t_ns_ = frame.t_ns;
  if (result.state == dsp::TrackingState::kLost) ++counters_.lost_frames;
  if (result.relocalised) ++counters_.relocalisations;
  if (result.new_segment) ++counters_.new_segments;
  if (result.map_full) ++counters_.map_full_keyframes;
  if (result.keyframe_deferred) ++counters_.keyframes_deferred;
  if (const dsp::KeyframeMessage* kf = tracker_.pending_keyframe()) {
    ++counters_.keyframes;
    if (options_.mapping_thread) {
      slot->epoch = epoch_;
      slot->message.copy_from(*kf);  // allowed above: the slot is there
      keyframes_.push();
      mapper_wakeup_.notify();
    } else {
      map_keyframe(*kf, lockstep_correction_);
      tracker_.apply(lockstep_correction_);
      ++counters_.corrections_applied;
      if (global_due(++lockstep_since_global_)) {
        lockstep_since_global_ = 0;
        global_adjust(lockstep_correction_);
        tracker_.apply(lockstep_correction_);
        ++counters_.corrections_applied;
      }
      publish_map();
    }
  }
  return result;
}

void TrackingAndMapping::map_keyframe(const dsp::KeyframeMessage& message,
                                      dsp::MapCorrection& out) {
  const TimeNs t0 = monotonic_now_ns();
  mapper_->add_keyframe(message);
  const dsp::MapperStats stats = mapper_->local_adjust(out);
  const TimeNs t1 = monotonic_now_ns();
  local_adjustments_.fetch_add(1, std::memory_order_relaxed);
  note(stats);
  const std::lock_guard<std::mutex> lock(map_mutex_);
  mapping_times_.push_back(t1 - t0);
}

bool TrackingAndMapping::global_due(int keyframes_since) const {
  return options_.global_adjustment_keyframes > 0 &&
         keyframes_since >= options_.global_adjustment_keyframes;
}

void TrackingAndMapping::global_adjust(dsp::MapCorrection& out) {
  const dsp::MapperStats stats = mapper_->global_adjust(out);
  global_adjustments_.fetch_add(1, std::memory_order_relaxed);
  note(stats);
}

void TrackingAndMapping::note(const dsp::MapperStats& stats) {
  culled_.fetch_add(static_cast<std::uint64_t>(stats.culled), std::memory_order_relaxed);
  culled_keyframes_.fetch_add(static_cast<std::uint64_t>(stats.culled_keyframes),
                              std::memory_order_relaxed);
  map_keyframes_.store(static_cast<std::uint64_t>(mapper_->keyframe_count()),
                       std::memory_order_relaxed);
  map_points_.store(static_cast<std::uint64_t>(mapper_->points_count()), std::memory_order_relaxed);
  stale_messages_.store(mapper_->stale_messages(), std::memory_order_relaxed);
}

void TrackingAndMapping::publish_map() {
  auto snapshot = std::make_shared<const dsp::MapSnapshot>(mapper_->snapshot());
  for (auto* channel : {options_.map_channel, options_.live_map_channel}) {
    if (channel == nullptr) continue;
    channel->back() = snapshot;
    channel->publish();
  }
  const std::lock_guard<std::mutex> lock(map_mutex_);
  map_ = std::move(snapshot);
}

void TrackingAndMapping::mapping_loop() {
  int since_global = 0;
  // Woken by a key-frame, a freed correction slot, a reset or the stop; the timeout is only a
  // backstop.
  constexpr DurationNs kBackstopNs = 200 * kNsPerMs;
  while (!stop_.load(std::memory_order_acquire)) {
    KeyframeSlot* kf = keyframes_.front();
    // Asked before any key-frame of its epoch was pushed, so read after the key-frame: never
    // older than the key-frame's epoch.
    const std::uint32_t asked = reset_epoch_.load(std::memory_order_acquire);
    if (asked != mapper_epoch_) {
      mapper_epoch_ = asked;
      since_global = 0;
      new_map();
    }
    if (kf != nullptr) {
      if (kf->epoch != mapper_epoch_) {  // the map before a reset
        keyframes_.pop();
        continue;
      }
      CorrectionSlot* out = corrections_.producer_slot();
      if (out == nullptr) {  // the tracker has not taken the last ones yet
        mapper_wakeup_.wait_for(kBackstopNs);
        continue;
      }
      if (options_.before_mapping) options_.before_mapping();
      map_keyframe(kf->message, out->correction);
      out->epoch = mapper_epoch_;
      keyframes_.pop();
      corrections_.push();
      publish_map();
      ++since_global;
      continue;
    }
    if (global_due(since_global)) {
      if (CorrectionSlot* out = corrections_.producer_slot()) {
        global_adjust(out->correction);
        out->epoch = mapper_epoch_;
        corrections_.push();
        publish_map();
        since_global = 0;
        continue;
      }
    }
    mapper_wakeup_.wait_for(kBackstopNs);
  }
}

std::shared_ptr<const dsp::MapSnapshot> TrackingAndMapping::finish() {
  if (thread_ && thread_->joinable()) {
    // Let the mapper take what is queued, then stop it. (front() is the consumer's: this
    // thread is the producer, so it may only ask how full the ring is.) Not the fixed-rate
    // path: the end of a run.
    while (keyframes_.size_approx() != 0) {
      bool freed = false;
      while (CorrectionSlot* c = corrections_.front()) {
        if (c->epoch == epoch_) tracker_.apply(c->correction);
        corrections_.pop();
        freed = true;
      }
      if (freed) mapper_wakeup_.notify();
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    stop_.store(true);
    mapper_wakeup_.notify();
    thread_->join();
    while (CorrectionSlot* c = corrections_.front()) {
      if (c->epoch == epoch_) tracker_.apply(c->correction);
      corrections_.pop();
    }
    // A reset the mapping thread had not seen yet (it was asleep, nothing queued).
    if (mapper_epoch_ != epoch_) {
      mapper_epoch_ = epoch_;
      new_map();
    }
  }
  if (mapper_->keyframe_count() > 0) {
    global_adjust(lockstep_correction_);
    tracker_.apply(lockstep_correction_);
  }
  publish_map();
  return latest_map();
}

std::shared_ptr<const dsp::MapSnapshot> TrackingAndMapping::latest_map() const {
  const std::lock_guard<std::mutex> lock(map_mutex_);
  return map_;
}

TrackingCounters TrackingAndMapping::counters() const {
  TrackingCounters c = counters_;
  c.local_adjustments = local_adjustments_.load();
  c.global_adjustments = global_adjustments_.load();
  c.culled_points = culled_.load();
  c.culled_keyframes = culled_keyframes_.load();
  c.map_keyframes = map_keyframes_.load();
  c.map_points = map_points_.load();
  c.stale_updates += stale_messages_.load();
  return c;
}

std::vector<std::int64_t> TrackingAndMapping::mapping_times_ns() const {
  const std::lock_guard<std::mutex> lock(map_mutex_);
  return mapping_times_;
}

}  // namespace wallar::firmware
