// SPDX-License-Identifier: Apache-2.0
/// @file replay_module.hpp
/// @brief The replay source module: a recording played on the replay thread as if it were the
/// sensors (drivers/source ReplaySource: the recording's time stamps, publish_t_ns at delivery
/// as a driver sets it), at its rate or as fast as the pipeline takes it.
///
/// The IMU stream ends with the cameras' (one frame period after the last frame): a
/// recording's IMU often runs on after its last frame, which would read as a lost camera at
/// its end. The product plays the recording once as it is. A ReplayPlan (test tooling,
/// firmware/hil) may play it several times, shifted in time, through sinks that withhold or corrupt
/// samples; the module only asks the plan for each loop's sink.
///
/// Threading: the constructor, start(), join_within() from the supervisor; the plan is called
/// on the replay thread only; stats(), loops_played() and injected() from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/firmware/appliance/source_module.hpp"
#include "wallar/firmware/board.hpp"

namespace wallar::firmware {

/// What the replay module plays, loop after loop.
class ReplayPlan {
 public:
  virtual ~ReplayPlan() = default;
  /// Before loop `loop` (0, 1, ...): the sink to play it into (it forwards to `pipeline`), or
  /// null when the plan is done.
  virtual source::SensorSink* begin_loop(int loop, source::SensorSink& pipeline) = 0;
  /// After each loop, with what it played.
  virtual void end_loop(const source::ReplayStats& loop) = 0;
  /// Samples withheld or corrupted so far; any thread.
  [[nodiscard]] virtual std::uint64_t injected() const = 0;
  /// ", 3 loops", ", looped", ... (appended to the module's description).
  [[nodiscard]] virtual std::string describe() const = 0;
};

class ReplayModule final : public SourceModule {
 public:
  /// `plan` may be null: the recording once, as it is. `board` (may be null; must outlive the
  /// module) places the replay thread.
  ReplayModule(const recording::EurocRecording& rec, const source::ReplayOptions& replay,
               std::unique_ptr<ReplayPlan> plan, const BoardConfig* board = nullptr);
  void start(source::SensorSink& sink, drivers::ImuSampleSink& imu_sink, bool realtime,
             const std::atomic<bool>& stop) override;
  [[nodiscard]] bool finished() const override { return done_.load(std::memory_order_acquire); }
  bool join_within(DurationNs timeout_ns) override;
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::vector<const RtThread*> threads() const override { return {thread_.get()}; }
  [[nodiscard]] std::exception_ptr error() const override;

  /// Summed over the loops played.
  [[nodiscard]] source::ReplayStats stats() const;
  [[nodiscard]] int loops_played() const;
  [[nodiscard]] std::uint64_t injected() const { return plan_ ? plan_->injected() : 0; }

 private:
  void accumulate(const source::ReplayStats& s);

  /// Drops IMU samples after the cameras' end.
  class EndWithCameras final : public source::SensorSink {
   public:
    explicit EndWithCameras(TimeNs imu_end_ns) : imu_end_ns_(imu_end_ns) {}
    void set_next(source::SensorSink& next) { next_ = &next; }
    void on_imu(const ImuSample& s) override {
      if (s.t_ns <= imu_end_ns_) next_->on_imu(s);
    }
    void on_stereo(const StereoFrame& f) override { next_->on_stereo(f); }
    void on_unpaired(int cam, const CameraFrame& f) override { next_->on_unpaired(cam, f); }

   private:
    TimeNs imu_end_ns_;
    source::SensorSink* next_ = nullptr;
  };

  const recording::EurocRecording& rec_;
  source::ReplayOptions replay_;
  std::unique_ptr<ReplayPlan> plan_;
  const BoardConfig* board_;
  EndWithCameras end_with_cameras_;
  std::unique_ptr<RtThread> thread_;
  std::atomic<bool> done_{false};
  mutable std::mutex mutex_;  // stats: written once per loop, read by the supervisor
  source::ReplayStats stats_;
  int loops_played_ = 0;
};

}  // namespace wallar::firmware
