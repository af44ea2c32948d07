// SPDX-License-Identifier: Apache-2.0
/// @file sensor_sink.hpp
/// @brief Where sensor sources (live drivers or replay) deliver samples.
///
/// A source calls the sink from its own thread. The same sink serves live capture and replay,
/// so nothing downstream can tell them apart; a recorder is just another sink.
///
/// Threading contract: a source calls on_imu() from one thread with strictly increasing
/// t_ns, and on_stereo()/on_unpaired() from one thread (maybe another) with increasing t_ns.
/// Sinks must not block for long: live sources drop and count what they cannot deliver.
#pragma once

#include "wallar/core/imu_sample.hpp"
#include "wallar/core/stereo_frame.hpp"

namespace wallar::source {

class SensorSink {
 public:
  virtual ~SensorSink() = default;
  virtual void on_imu(const ImuSample& sample) = 0;
  virtual void on_stereo(const StereoFrame& frame) = 0;
  /// A camera frame that found no partner within the pairing tolerance (cam 0 = left).
  virtual void on_unpaired(int cam, const CameraFrame& frame) {
    (void)cam;
    (void)frame;
  }
};

}  // namespace wallar::source
