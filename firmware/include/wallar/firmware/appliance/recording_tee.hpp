// SPDX-License-Identifier: Apache-2.0
/// @file recording_tee.hpp
/// @brief The source's samples to the recorder and to the pipeline (`wallar run --record`):
/// each IMU sample and frame goes to the AsyncRecorder's rings first (a copy of the pixels
/// into a slot, or a counted drop: never a wait), then to the pipeline as without it.
///
/// Threading: called from the source's threads, as the pipeline is (one IMU producer, one
/// frame producer); the recorder and the pipeline outlive it.
#pragma once

#include "wallar/drivers/source/async_recorder.hpp"
#include "wallar/firmware/appliance/pipeline_sink.hpp"

namespace wallar::firmware {

class RecordingTee final : public source::SensorSink, public drivers::ImuSampleSink {
 public:
  RecordingTee(PipelineSink& pipeline, source::AsyncRecorder& recorder)
      : pipeline_(pipeline), recorder_(recorder) {}

  void on_imu(const ImuSample& s) override {
    recorder_.on_imu(s);
    pipeline_.on_imu(s);
  }
  void on_imu_sample(const ImuSample& s) noexcept override {
    recorder_.on_imu_sample(s);
    pipeline_.on_imu_sample(s);
  }
  void on_stereo(const StereoFrame& f) override {
    recorder_.on_stereo(f);
    pipeline_.on_stereo(f);
  }
  void on_unpaired(int cam, const CameraFrame& f) override {
    recorder_.on_unpaired(cam, f);
    pipeline_.on_unpaired(cam, f);
  }

 private:
  PipelineSink& pipeline_;
  source::AsyncRecorder& recorder_;
};

}  // namespace wallar::firmware
