// SPDX-License-Identifier: Apache-2.0
/// @file replay_source.hpp
/// @brief Plays an EuRoC recording into a SensorSink as if it were live.
///
/// IMU samples and camera frames are merged in time order and delivered at real time, at N x,
/// or as fast as possible. Samples keep the recording's timestamps (the recording's clock);
/// publish_t_ns is CLOCK_MONOTONIC at delivery, as a live driver sets it. Stereo frames go
/// through the same StereoPairer as live capture; unpaired frames are counted and handed to
/// the sink.
///
/// Threading: run() blocks the calling thread until the end of the recording or until `stop`
/// becomes true; the sink is called from that thread only.
#pragma once

#include <atomic>
#include <cstdint>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/source/sensor_sink.hpp"
#include "wallar/drivers/sync/stereo_pairer.hpp"

namespace wallar::source {

struct ReplayOptions {
  double rate = 1.0;                  //!< 1 = real time, 2 = twice as fast, 0 = as fast as possible
  DurationNs start_offset_ns = 0;     //!< skip this much of the recording's start
  std::uint32_t skip = 0;             //!< after each stereo pair played, skip this many
  DurationNs pair_tolerance_ns = -1;  //!< < 0: half the camera frame period from sensor.yaml
  bool with_images = true;            //!< false: deliver frames without decoding pixels (stats)
};

struct ReplayStats {
  std::uint64_t imu_samples = 0;
  std::array<std::uint64_t, 2> frames{0, 0};  //!< camera frames read, per camera
  std::uint64_t pairs_delivered = 0;
  std::uint64_t pairs_skipped = 0;  //!< by the skip option
  sync::PairingStats pairing;
  DurationNs pair_tolerance_ns = 0;  //!< the pairing tolerance used
  TimeNs first_t_ns = 0;
  TimeNs last_t_ns = 0;
  DurationNs wall_time_ns = 0;     //!< how long the replay took
  DurationNs max_lateness_ns = 0;  //!< worst delivery behind schedule (paced replay)
  bool stopped = false;            //!< ended by `stop` before the end
};

class ReplaySource {
 public:
  ReplaySource(const recording::EurocRecording& recording, ReplayOptions options);

  /// Plays the recording into `sink`; throws InputError if an image cannot be read.
  ReplayStats run(SensorSink& sink, const std::atomic<bool>& stop);

  [[nodiscard]] DurationNs pair_tolerance_ns() const { return tolerance_ns_; }

 private:
  const recording::EurocRecording& rec_;
  ReplayOptions options_;
  DurationNs tolerance_ns_;
};

}  // namespace wallar::source
