// SPDX-License-Identifier: Apache-2.0
/// @file pipeline_sink.cpp
/// @brief Source -> tracking channels: the IMU ring, the frame mailbox, the hand-off modes.
#include "wallar/firmware/appliance/pipeline_sink.hpp"

namespace wallar::firmware {

PipelineSink::PipelineSink(Wakeup& tracking, const std::atomic<bool>& stop, bool every_frame)
    : tracking_(tracking), stop_(stop), every_frame_(every_frame), imu_(kImuRingSlots) {}

void PipelineSink::on_imu(const ImuSample& s) {
  ImuSample* slot = imu_.producer_slot();
  while (slot == nullptr && every_frame_ && !stop_.load(std::memory_order_acquire)) {
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

void PipelineSink::on_stereo(const StereoFrame& f) {
  last_delivered_t_ns_.store(f.t_ns, std::memory_order_relaxed);
  frames_.post(f);
  frames_in_.fetch_add(1, std::memory_order_release);
  tracking_.notify();
  if (!every_frame_) return;
  // Every frame: wait until tracking took this one, so none is overwritten.
  while (frames_taken_.load(std::memory_order_acquire) < frames_in_.load() &&
         !stop_.load(std::memory_order_acquire)) {
    taken_.wait_for(50 * kNsPerMs);
  }
}

void PipelineSink::on_unpaired(int /*cam*/, const CameraFrame& /*f*/) {
  unpaired_.fetch_add(1, std::memory_order_relaxed);
}

void PipelineSink::frame_done() {
  frames_taken_.fetch_add(1, std::memory_order_release);
  if (every_frame_) taken_.notify();
}

void PipelineSink::imu_room() {
  if (every_frame_) taken_.notify();
}

bool PipelineSink::drained() const {
  return frames_taken_.load() + frames_.overwritten() >= frames_in_.load() &&
         imu_.size_approx() == 0;
}

}  // namespace wallar::firmware
