// SPDX-License-Identifier: Apache-2.0
/// @file replay_module.cpp
/// @brief The replay thread: the recording into the pipeline, loop by loop as the plan says.
#include "wallar/firmware/appliance/replay_module.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>

#include "wallar/firmware/appliance/thread_table.hpp"

namespace wallar::firmware {

ReplayModule::ReplayModule(const recording::EurocRecording& rec,
                           const source::ReplayOptions& replay, std::unique_ptr<ReplayPlan> plan,
                           const BoardConfig* board)
    : rec_(rec),
      replay_(replay),
      plan_(std::move(plan)),
      board_(board),
      end_with_cameras_(rec.cams[0].frames.empty()
                            ? std::numeric_limits<TimeNs>::max()
                            : rec.cams[0].frames.back().t_ns + frame_period_of(rec.cams[0].calib)) {
}

void ReplayModule::start(source::SensorSink& sink, drivers::ImuSampleSink& /*imu_sink*/,
                         bool realtime, const std::atomic<bool>& stop) {
  thread_ =
      std::make_unique<RtThread>(thread_spec("replay", realtime, board_), [this, &sink, &stop] {
        const SetOnExit done(done_);
        for (int loop = 0; !stop.load(); ++loop) {
          source::SensorSink* into = plan_       ? plan_->begin_loop(loop, sink)
                                     : loop == 0 ? &sink
                                                 : nullptr;
          if (into == nullptr) break;
          end_with_cameras_.set_next(*into);
          source::ReplaySource source(rec_, replay_);
          const source::ReplayStats s = source.run(end_with_cameras_, stop);
          accumulate(s);
          if (plan_) plan_->end_loop(s);
          if (s.pairs_delivered == 0 && s.imu_samples == 0) break;
        }
      });
}

bool ReplayModule::join_within(DurationNs timeout_ns) {
  return join_source_thread(thread_.get(), done_, timeout_ns);
}

std::string ReplayModule::describe() const {
  char rate[32] = "full speed";
  if (replay_.rate > 0) std::snprintf(rate, sizeof rate, "%gx", replay_.rate);
  char buf[600];
  std::snprintf(buf, sizeof buf, "replay of %s at %s", rec_.mav0.parent_path().string().c_str(),
                rate);
  return plan_ ? buf + plan_->describe() : std::string(buf);
}

std::exception_ptr ReplayModule::error() const { return source_thread_error(thread_.get()); }

source::ReplayStats ReplayModule::stats() const {
  const std::lock_guard lock(mutex_);
  return stats_;
}

int ReplayModule::loops_played() const {
  const std::lock_guard lock(mutex_);
  return loops_played_;
}

void ReplayModule::accumulate(const source::ReplayStats& s) {
  const std::lock_guard lock(mutex_);
  if (loops_played_ == 0) {
    stats_ = s;
  } else {
    stats_.imu_samples += s.imu_samples;
    stats_.frames[0] += s.frames[0];
    stats_.frames[1] += s.frames[1];
    stats_.pairs_delivered += s.pairs_delivered;
    stats_.pairs_skipped += s.pairs_skipped;
    stats_.wall_time_ns += s.wall_time_ns;
    stats_.max_lateness_ns = std::max(stats_.max_lateness_ns, s.max_lateness_ns);
    stats_.stopped = s.stopped;
  }
  ++loops_played_;
}

}  // namespace wallar::firmware
