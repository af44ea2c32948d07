// SPDX-License-Identifier: Apache-2.0
/// @file pipeline_sink.hpp
/// @brief The channels from a source module toward the tracking module: IMU samples through
/// an SPSC ring (every sample matters; a full ring drops and counts), stereo frames through a
/// newest-only mailbox of counted references (latency matters; an overwritten frame is
/// counted), and a wake-up for the tracking thread. Producers never allocate.
///
/// Hand-off: in real time a frame not yet taken is overwritten by the next one; with
/// `every_frame` (offline, replay only) the producer waits until tracking took each frame and
/// the IMU ring has room, so nothing is lost and the replay goes as fast as tracking does.
///
/// Threading: on_imu()/on_imu_sample() from one producer thread, on_stereo()/on_unpaired()
/// from one producer thread (may be the same); imu_front(), imu_pop(), take_frame(),
/// frame_done() and imu_room() from the tracking thread; the counters from any thread.
#pragma once

#include <atomic>
#include <cstdint>

#include "wallar/core/mailbox.hpp"
#include "wallar/core/spsc_ring.hpp"
#include "wallar/drivers/imu/imu_driver.hpp"
#include "wallar/drivers/source/sensor_sink.hpp"
#include "wallar/firmware/wakeup.hpp"

namespace wallar::firmware {

class PipelineSink final : public source::SensorSink, public drivers::ImuSampleSink {
 public:
  static constexpr std::size_t kImuRingSlots =
      4096;  // 20 s at 200 Hz: drops only if tracking hangs

  PipelineSink(Wakeup& tracking, const std::atomic<bool>& stop, bool every_frame);

  // Producer side.
  void on_imu(const ImuSample& s) override;
  void on_imu_sample(const ImuSample& s) noexcept override { on_imu(s); }
  void on_stereo(const StereoFrame& f) override;
  void on_unpaired(int cam, const CameraFrame& f) override;

  // Consumer side (tracking thread).
  ImuSample* imu_front() { return imu_.front(); }
  void imu_pop() { imu_.pop(); }
  bool take_frame(StereoFrame& out) { return frames_.take(out); }
  /// The frame taken last is done with: an every-frame producer may deliver the next.
  void frame_done();
  /// Samples were popped: an every-frame producer waiting for room may go on.
  void imu_room();
  /// Stop: releases a producer waiting in every-frame hand-off.
  void release_producers() { taken_.notify(); }
  /// Every frame delivered was tracked or overwritten, and the IMU ring is empty.
  [[nodiscard]] bool drained() const;

  [[nodiscard]] bool every_frame() const { return every_frame_; }
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
  bool every_frame_;
  SpscRing<ImuSample> imu_;
  NewestMailbox<StereoFrame> frames_;
  Wakeup taken_;
  TimeNs last_imu_notify_t_ns_ = 0;
  std::atomic<TimeNs> last_delivered_t_ns_{-1};
  std::atomic<std::uint64_t> imu_in_{0}, imu_dropped_{0}, frames_in_{0}, frames_taken_{0},
      unpaired_{0};
};

}  // namespace wallar::firmware
