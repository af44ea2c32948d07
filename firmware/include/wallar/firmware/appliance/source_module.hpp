// SPDX-License-Identifier: Apache-2.0
/// @file source_module.hpp
/// @brief The source side of the appliance behind one interface: a replay of a recording
/// (replay_module.hpp) or the live drivers (live_module.hpp). The pipeline cannot tell them
/// apart: both deliver into a SensorSink and an ImuSampleSink from their own threads.
///
/// Threading: start(), join_within() and the destructor from the supervisor; finished(),
/// error() and threads() from any thread while it runs.
#pragma once

#include <atomic>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/core/heartbeat.hpp"
#include "wallar/core/time.hpp"
#include "wallar/drivers/imu/imu_driver.hpp"
#include "wallar/drivers/source/sensor_sink.hpp"
#include "wallar/firmware/rt_thread.hpp"

namespace wallar::firmware {

class SourceModule {
 public:
  virtual ~SourceModule() = default;
  /// Opens what it needs (live: the devices, which may throw) and starts its threads.
  virtual void start(source::SensorSink& sink, drivers::ImuSampleSink& imu_sink, bool realtime,
                     const std::atomic<bool>& stop) = 0;
  [[nodiscard]] virtual bool finished() const = 0;
  /// Phase two of the stop: waits up to `timeout_ns` for the threads to end; false if one is
  /// stuck (in a device call).
  virtual bool join_within(DurationNs timeout_ns) = 0;
  [[nodiscard]] virtual std::string describe() const = 0;
  [[nodiscard]] virtual std::vector<const RtThread*> threads() const = 0;
  /// Allocations one of threads() made after its start-up (null: not counted; a replay decodes
  /// images, it is not a device path).
  [[nodiscard]] virtual const std::atomic<std::uint64_t>* allocations_of(
      const RtThread* /*thread*/) const {
    return nullptr;
  }
  /// The source's device loops and their progress ({"capture", ...}, {"imu", ...}), for the
  /// supervisor's health check; after start(). Empty for a replay: not a device, and a replay
  /// that stops delivering shows as a lost camera.
  [[nodiscard]] virtual std::vector<std::pair<const char*, const Heartbeat*>> heartbeats() const {
    return {};
  }
  /// The exception a source thread ended with (null if none), e.g. the replay's InputError for
  /// an image that cannot be read.
  [[nodiscard]] virtual std::exception_ptr error() const = 0;
  /// Each device's driver counters ({"left", "frames=.. reopens=.."}, ...), one line per
  /// device; empty for a replay. Only after join_within() returned true.
  [[nodiscard]] virtual std::vector<std::pair<std::string, std::string>> device_counters() const {
    return {};
  }
};

/// The camera's frame period (20 Hz when its rate is unknown).
inline DurationNs frame_period_of(const CameraCalibration& cam) {
  return cam.rate_hz > 0 ? static_cast<DurationNs>(1e9 / cam.rate_hz) : 50 * kNsPerMs;
}

/// Sets `flag` when the scope ends, also by an exception: a source thread says it is done
/// either way, so the stop never waits for a thread that already failed.
class SetOnExit {
 public:
  explicit SetOnExit(std::atomic<bool>& flag) : flag_(flag) {}
  ~SetOnExit() { flag_.store(true, std::memory_order_release); }
  SetOnExit(const SetOnExit&) = delete;
  SetOnExit& operator=(const SetOnExit&) = delete;

 private:
  std::atomic<bool>& flag_;
};

/// Waits until `flag` is set or `timeout_ns` passed; true when it was set.
bool wait_flag(const std::atomic<bool>& flag, DurationNs timeout_ns);

/// A source module's one thread (null: never started): waits up to `timeout_ns` for `done`
/// (or the thread's failure) and joins it; false if it is still running.
bool join_source_thread(RtThread* thread, const std::atomic<bool>& done, DurationNs timeout_ns);
/// The exception the thread ended with; null if none (or never started).
std::exception_ptr source_thread_error(const RtThread* thread);

}  // namespace wallar::firmware
