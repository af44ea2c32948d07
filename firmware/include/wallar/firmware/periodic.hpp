// SPDX-License-Identifier: Apache-2.0
/// @file periodic.hpp
/// @brief A fixed-rate loop's clock: absolute CLOCK_MONOTONIC deadlines start + k * period,
/// slept to with clock_nanosleep(TIMER_ABSTIME) so the rate does not drift with the loop's
/// own run time, and overruns counted instead of caught up in a burst.
///
/// wait() sleeps until the next deadline and returns it. When the wake-up is so late that the
/// following deadline has passed too (the loop overran, or the thread was not scheduled), the
/// deadlines already in the past are skipped: misses() grows by the whole periods lost and the
/// next deadline is the first one in the future, still on the start + k * period grid.
///
/// Threading: one thread owns the timer and calls wait(); the counters are plain fields, read
/// them on that thread. Nothing allocates.
#pragma once

#include <cerrno>
#include <cstdint>
#include <ctime>
#include <stdexcept>

#include "wallar/core/time.hpp"

namespace wallar::firmware {

class PeriodicTimer {
 public:
  /// Deadlines start_ns + k * period_ns for k = 1, 2, ...; throws std::invalid_argument for a
  /// period that is not positive.
  explicit PeriodicTimer(DurationNs period_ns, TimeNs start_ns = monotonic_now_ns())
      : period_ns_(period_ns), start_ns_(start_ns), next_ns_(start_ns + period_ns) {
    if (period_ns <= 0) throw std::invalid_argument("PeriodicTimer: period must be positive");
  }

  /// Sleeps until the next deadline (retrying when a signal interrupts) and returns it. If the
  /// wake-up is a period or more late, the missed deadlines are counted and skipped.
  TimeNs wait() {
    const TimeNs deadline_ns = next_ns_;
    const timespec ts = ns_to_timespec(deadline_ns < 0 ? 0 : deadline_ns);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const TimeNs now_ns = monotonic_now_ns();
    lateness_ns_ = now_ns - deadline_ns;
    if (lateness_ns_ > max_lateness_ns_) max_lateness_ns_ = lateness_ns_;
    ++wakeups_;
    next_ns_ = deadline_ns + period_ns_;
    if (now_ns >= next_ns_) {  // the following deadline has passed as well
      const DurationNs lost = lateness_ns_ / period_ns_;  // >= 1 whole periods
      misses_ += static_cast<std::uint64_t>(lost);
      next_ns_ = deadline_ns + (lost + 1) * period_ns_;  // the first deadline after now
    }
    return deadline_ns;
  }

  [[nodiscard]] DurationNs period_ns() const { return period_ns_; }
  [[nodiscard]] TimeNs start_ns() const { return start_ns_; }
  /// The deadline the next wait() sleeps to.
  [[nodiscard]] TimeNs next_deadline_ns() const { return next_ns_; }
  /// Deadlines skipped because a wake-up came a period or more late.
  [[nodiscard]] std::uint64_t misses() const { return misses_; }
  /// How late the last wake-up was (now - deadline; 0 before the first wait()).
  [[nodiscard]] DurationNs lateness_ns() const { return lateness_ns_; }
  [[nodiscard]] DurationNs max_lateness_ns() const { return max_lateness_ns_; }
  /// Completed wait() calls.
  [[nodiscard]] std::uint64_t wakeups() const { return wakeups_; }

 private:
  DurationNs period_ns_;
  TimeNs start_ns_;
  TimeNs next_ns_;
  std::uint64_t misses_ = 0;
  std::uint64_t wakeups_ = 0;
  DurationNs lateness_ns_ = 0;
  DurationNs max_lateness_ns_ = 0;
};

}  // namespace wallar::firmware
