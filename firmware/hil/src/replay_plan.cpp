// SPDX-License-Identifier: Apache-2.0
/// @file replay_plan.cpp
/// @brief Loops and faults between the replay and the pipeline.
#include "wallar/firmware/hil/replay_plan.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <optional>

#include "wallar/firmware/hil/loop_shift.hpp"

namespace wallar::firmware::hil {
namespace {

class HilPlan final : public ReplayPlan {
 public:
  HilPlan(const recording::EurocRecording& rec, int loops, std::vector<FaultSpec> faults)
      : loops_(loops),
        faults_(std::move(faults)),
        period_ns_(frame_period_of(rec.cams[0].calib)),
        // The IMU stream ends with the cameras' (the replay module drops the rest).
        imu_end_ns_(rec.cams[0].frames.empty() ? std::numeric_limits<TimeNs>::max()
                                               : rec.cams[0].frames.back().t_ns + period_ns_) {}

  source::SensorSink* begin_loop(int loop, source::SensorSink& pipeline) override {
    if (loops_ != 0 && loop >= loops_) return nullptr;
    if (!shift_) {
      faults_sink_.emplace(pipeline, faults_);
      shift_.emplace(*faults_sink_);
    }
    shift_->set_offset(offset_ns_);
    return &*shift_;
  }
  void end_loop(const source::ReplayStats& s) override {
    offset_ns_ += (std::min(s.last_t_ns, imu_end_ns_) - s.first_t_ns) + period_ns_;
  }
  [[nodiscard]] std::uint64_t injected() const override {
    return faults_sink_ ? faults_sink_->injected() : 0;
  }
  [[nodiscard]] std::string describe() const override {
    char buf[48] = "";
    if (loops_ == 0) std::snprintf(buf, sizeof buf, ", looped");
    if (loops_ > 1) std::snprintf(buf, sizeof buf, ", %d loops", loops_);
    std::string s = buf;
    for (const FaultSpec& f : faults_) s += ", fault " + to_string(f);
    return s;
  }

 private:
  int loops_;
  std::vector<FaultSpec> faults_;
  DurationNs period_ns_;
  TimeNs imu_end_ns_;
  DurationNs offset_ns_ = 0;
  std::optional<FaultSink> faults_sink_;
  std::optional<LoopShift> shift_;
};

}  // namespace

std::function<std::unique_ptr<ReplayPlan>(const recording::EurocRecording&)> replay_plan(
    int loops, std::vector<FaultSpec> faults) {
  return [loops, faults](const recording::EurocRecording& rec) -> std::unique_ptr<ReplayPlan> {
    return std::make_unique<HilPlan>(rec, loops, faults);
  };
}

}  // namespace wallar::firmware::hil
