// SPDX-License-Identifier: Apache-2.0
/// @file loop_shift.hpp
/// @brief Loop shifting for soak and HIL tests (`wallar run --loop N`): shifts a replayed
/// loop's time stamps past the previous loop's, so sensor time keeps increasing. Test tooling,
/// not part of the product's modules.
///
/// Threading: one thread (the replay's) calls the sink and set_offset() between loops.
#pragma once

#include "wallar/drivers/source/sensor_sink.hpp"

namespace wallar::firmware::hil {

class LoopShift final : public source::SensorSink {
 public:
  explicit LoopShift(source::SensorSink& next) : next_(next) {}
  void set_offset(DurationNs offset_ns) { offset_ns_ = offset_ns; }
  void on_imu(const ImuSample& s) override;
  void on_stereo(const StereoFrame& f) override;
  void on_unpaired(int cam, const CameraFrame& f) override { next_.on_unpaired(cam, f); }

 private:
  source::SensorSink& next_;
  DurationNs offset_ns_ = 0;
};

}  // namespace wallar::firmware::hil
