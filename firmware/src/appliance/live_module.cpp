// SPDX-License-Identifier: Apache-2.0
/// @file live_module.cpp
/// @brief The capture and imu threads of a live board.
#include "wallar/firmware/appliance/live_module.hpp"

#include <algorithm>
#include <limits>

#include "wallar/firmware/appliance/allocation_count.hpp"
#include "wallar/firmware/appliance/thread_table.hpp"

namespace wallar::firmware {

void LiveModule::start(source::SensorSink& sink, drivers::ImuSampleSink& imu_sink, bool realtime,
                       const std::atomic<bool>& stop) {
  // Devices open here, before any thread: a missing one is an error at start.
  cameras_ = std::make_unique<LiveStereo>(board_, sink, LiveStereo::Log{},
                                          drivers::linux_v4l2_system(), log_);
  if (board_.imu.driver != "none") imu_ = std::make_unique<LiveImu>(board_, imu_sink, log_);
  capture_ = std::make_unique<RtThread>(thread_spec("capture", realtime, &board_), [this, &stop] {
    const SetOnExit done(capture_done_);
    tl_allocation_counter = &capture_allocs_;  // the devices are open: none from here on
    cameras_->run(std::numeric_limits<TimeNs>::max(), stop);
    tl_allocation_counter = nullptr;
  });
  if (imu_) {
    imu_thread_ = std::make_unique<RtThread>(thread_spec("imu", realtime, &board_), [this, &stop] {
      const SetOnExit done(imu_done_);
      tl_allocation_counter = &imu_allocs_;
      imu_->run(std::numeric_limits<TimeNs>::max(), stop);
      tl_allocation_counter = nullptr;
    });
  } else {
    imu_done_.store(true);
  }
}

bool LiveModule::join_within(DurationNs timeout_ns) {
  const TimeNs until = monotonic_now_ns() + timeout_ns;
  if (capture_ && !wait_flag(capture_done_, until - monotonic_now_ns()) && !capture_->failed())
    return false;
  if (imu_thread_ && !wait_flag(imu_done_, std::max<DurationNs>(0, until - monotonic_now_ns())) &&
      !imu_thread_->failed())
    return false;
  if (capture_) capture_->join();
  if (imu_thread_) imu_thread_->join();
  return true;
}

std::string LiveModule::describe() const {
  return cameras_ ? cameras_->description() + (imu_ ? "; " + imu_->description() : "; no IMU")
                  : "live sensors";
}

std::vector<const RtThread*> LiveModule::threads() const {
  std::vector<const RtThread*> t{capture_.get()};
  if (imu_thread_) t.push_back(imu_thread_.get());
  return t;
}

const std::atomic<std::uint64_t>* LiveModule::allocations_of(const RtThread* thread) const {
  if (thread != nullptr && thread == capture_.get()) return &capture_allocs_;
  if (thread != nullptr && thread == imu_thread_.get()) return &imu_allocs_;
  return nullptr;
}

std::vector<std::pair<const char*, const Heartbeat*>> LiveModule::heartbeats() const {
  std::vector<std::pair<const char*, const Heartbeat*>> out;
  if (cameras_) out.emplace_back("capture", &cameras_->capture().heartbeat());
  if (imu_) out.emplace_back("imu", &imu_->heartbeat());
  return out;
}

std::vector<std::pair<std::string, std::string>> LiveModule::device_counters() const {
  std::vector<std::pair<std::string, std::string>> out;
  if (cameras_) {
    out.emplace_back("left", drivers::format_counters(cameras_->capture().camera(0).counters()));
    out.emplace_back("right", drivers::format_counters(cameras_->capture().camera(1).counters()));
  }
  if (imu_) out.emplace_back("imu", drivers::format_counters(imu_->driver().counters()));
  return out;
}

std::exception_ptr LiveModule::error() const {
  if (capture_ && capture_->failed()) return capture_->exception();
  if (imu_thread_ && imu_thread_->failed()) return imu_thread_->exception();
  return {};
}

}  // namespace wallar::firmware
