// SPDX-License-Identifier: Apache-2.0
/// @file heartbeat.hpp
/// @brief The progress of one thread, for the supervisor's health check: the watchdog is fed
/// only while every fixed-rate thread and the display make progress.
///
/// Two kinds of thread. A *loop* (capture, IMU, tracking) wakes at least every few tens of
/// milliseconds whatever its input, and beats each time: it is stalled once its last beat is
/// older than the limit. A *job* thread (render, reconstruction) may rightly sleep for as long
/// as it has nothing to do, so it brackets each piece of work with begin()/end(): it is
/// stalled once a piece of work has run longer than the limit (a draw stuck in a page flip, a
/// wall search that never returns).
///
/// Threading: one writer (the thread it describes), any number of readers; lock-free, never
/// allocates, never blocks.
#pragma once

#include <atomic>

#include "wallar/core/time.hpp"

namespace wallar {

class Heartbeat {
 public:
  enum class Kind : std::uint8_t { kLoop, kJob };
  /// `start_ns`: a loop's first beat, when it is built (then a thread that never starts reads
  /// as silent too); 0: silent only once it has beaten.
  explicit Heartbeat(Kind kind = Kind::kLoop, TimeNs start_ns = 0)
      : kind_(kind), last_ns_(start_ns) {}

  /// A loop's iteration (kLoop).
  void beat(TimeNs now_ns) { last_ns_.store(now_ns, std::memory_order_relaxed); }
  /// A job starts / ends (kJob).
  void begin(TimeNs now_ns) { busy_since_ns_.store(now_ns, std::memory_order_relaxed); }
  void end(TimeNs now_ns) {
    busy_since_ns_.store(0, std::memory_order_relaxed);
    last_ns_.store(now_ns, std::memory_order_relaxed);
  }

  /// How long it has shown no progress at `now_ns`: since the last beat (a loop that has
  /// beaten at least once), or since its job began (a job running); 0 otherwise.
  [[nodiscard]] DurationNs silent_ns(TimeNs now_ns) const {
    if (kind_ == Kind::kJob) {
      const TimeNs since = busy_since_ns_.load(std::memory_order_relaxed);
      return since > 0 ? now_ns - since : 0;
    }
    const TimeNs last = last_ns_.load(std::memory_order_relaxed);
    return last > 0 ? now_ns - last : 0;
  }
  /// The last beat or job end (0: none yet).
  [[nodiscard]] TimeNs last_ns() const { return last_ns_.load(std::memory_order_relaxed); }
  [[nodiscard]] Kind kind() const { return kind_; }

 private:
  Kind kind_;
  std::atomic<TimeNs> last_ns_{0};
  std::atomic<TimeNs> busy_since_ns_{0};
};

}  // namespace wallar
