// SPDX-License-Identifier: Apache-2.0
/// @file recorder_sink.hpp
/// @brief The recorder is just another sink: everything it receives goes to a RecordingWriter,
/// frames that found no stereo partner included (nothing recorded is lost).
///
/// Threading: the sink contract of sensor_sink.hpp; the writer is used from the calling
/// thread(s) only, so IMU and camera callbacks must come from one thread (as replay does).
#pragma once

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/source/sensor_sink.hpp"

namespace wallar::source {

class RecorderSink final : public SensorSink {
 public:
  explicit RecorderSink(recording::RecordingWriter& writer) : writer_(writer) {}
  void on_imu(const ImuSample& s) override { writer_.write_imu(s); }
  void on_stereo(const StereoFrame& f) override { writer_.write_stereo(f); }
  void on_unpaired(int cam, const CameraFrame& f) override { writer_.write_camera(cam, f); }

 private:
  recording::RecordingWriter& writer_;
};

}  // namespace wallar::source
