// SPDX-License-Identifier: Apache-2.0
/// @file push_module.hpp
/// @brief The push-fed source module: IMU samples and single camera images handed in by
/// callers outside the appliance (the VIT library's push calls, made from Monado's IMU and
/// camera threads), played into the pipeline as the replay module plays a recording.
///
/// Pushes never wait for the pipeline: each stream has a bounded queue, and a push into a full
/// queue is refused (kFull, counted) for the caller to drop or retry. The module's thread
/// merges the two streams in time order as the replay does (IMU first on ties; a camera image
/// goes once an IMU sample at or after its time was pushed, an IMU sample once an image at or
/// after its time was pushed), pairs the cameras' images by time stamp into stereo frames
/// (StereoPairer, half a frame period of tolerance as the replay) and delivers them into the
/// sink. In every-frame and lock-step modes the sink waits there until tracking took each
/// frame, so pushes made in time order are tracked exactly as a replay of the same samples
/// (`wallar track --lockstep`). A stream that falls silent holds the other for at most
/// `stall_ns` of wall time, then the other goes alone (a lost camera or IMU stays visible to
/// the degraded modes); a rig without an IMU (`imu` false) never waits for one.
///
/// end_of_stream() says no more samples come: the thread delivers what is queued, then the
/// pairer's last frame, and finishes.
///
/// Threading: push_imu() from one thread with strictly increasing t_ns; push_image() from one
/// thread (may be another) with each camera's t_ns increasing; end_of_stream(), counters() from
/// any thread; start(), join_within() from the supervisor. Pushes are lock-free (a slot of a
/// single-producer ring per stream, then a semaphore post) and allocate nothing; the image's
/// pixels come in as the caller's counted buffer.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "wallar/core/spsc_ring.hpp"
#include "wallar/drivers/sync/stereo_pairer.hpp"
#include "wallar/firmware/appliance/source_module.hpp"
#include "wallar/firmware/wakeup.hpp"

namespace wallar::firmware {

struct PushModuleOptions {
  std::size_t imu_capacity = 4096;       //!< queued IMU samples (20 s at 200 Hz)
  std::size_t image_capacity = 16;       //!< queued camera images, both cameras together
  DurationNs pair_tolerance_ns = 0;      //!< largest left/right skew of a stereo pair (> 0)
  bool imu = true;                       //!< the rig has an IMU: images wait for it
  DurationNs stall_ns = 250 * kNsPerMs;  //!< how long one stream waits for the other
};

enum class PushResult : std::uint8_t {
  kAccepted,
  kFull,        //!< the stream's queue is full: not taken (counted)
  kOutOfOrder,  //!< not after the stream's previous sample: not taken (counted)
  kClosed,      //!< after end_of_stream(), or once the module stopped
};

struct PushCounters {
  std::uint64_t imu_in = 0, imu_full = 0, imu_out_of_order = 0;
  std::uint64_t images_in = 0, images_full = 0, images_out_of_order = 0;
  std::uint64_t imu_delivered = 0, pairs_delivered = 0, unpaired = 0;
};

class PushModule final : public SourceModule {
 public:
  explicit PushModule(const PushModuleOptions& options);
  ~PushModule() override;
  PushModule(const PushModule&) = delete;
  PushModule& operator=(const PushModule&) = delete;

  PushResult push_imu(const ImuSample& sample);
  /// `cam` 0 (left) or 1 (right, else kOutOfOrder); the frame's image is taken as it is (a
  /// counted reference).
  PushResult push_image(int cam, CameraFrame frame);
  void end_of_stream();
  [[nodiscard]] PushCounters counters() const;
  /// True once start() ran (the appliance built its modules and started its threads).
  [[nodiscard]] bool started() const { return started_.load(std::memory_order_acquire); }

  void start(source::SensorSink& sink, drivers::ImuSampleSink& imu_sink, bool realtime,
             const std::atomic<bool>& stop) override;
  [[nodiscard]] bool finished() const override { return done_.load(std::memory_order_acquire); }
  bool join_within(DurationNs timeout_ns) override;
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::vector<const RtThread*> threads() const override { return {thread_.get()}; }
  [[nodiscard]] std::exception_ptr error() const override;

 private:
  struct QueuedImage {
    int cam = 0;
    CameraFrame frame;
  };
  void run(source::SensorSink& sink, const std::atomic<bool>& stop);

  PushModuleOptions options_;
  SpscRing<ImuSample> imu_;
  SpscRing<QueuedImage> images_;
  Wakeup pushed_;
  // Producer side: each written by its stream's pusher only, read by the module's thread.
  std::atomic<TimeNs> last_imu_t_ns_{-1};                       //!< the newest IMU sample taken
  std::array<std::atomic<TimeNs>, 2> last_image_t_ns_{-1, -1};  //!< the newest image per camera
  std::atomic<bool> ended_{false};
  std::atomic<std::uint64_t> imu_in_{0}, imu_full_{0}, imu_out_of_order_{0};
  std::atomic<std::uint64_t> images_in_{0}, images_full_{0}, images_out_of_order_{0};
  std::atomic<std::uint64_t> imu_delivered_{0}, pairs_delivered_{0}, unpaired_{0};
  sync::StereoPairer pairer_;  //!< the module's thread only
  std::unique_ptr<RtThread> thread_;
  std::atomic<bool> started_{false}, done_{false};
};

}  // namespace wallar::firmware
