// SPDX-License-Identifier: Apache-2.0
/// @file wakeup.hpp
/// @brief A counting wake-up over a POSIX semaphore: producers (threads or signal handlers)
/// notify without ever blocking, one consumer sleeps until notified or until a deadline.
///
/// Each notify() wakes one wait (they are counted); drain() forgets pending notifications,
/// e.g. when the waiter is about to look at everything anyway. The wake-up carries no data:
/// pass data through a channel (SpscRing, NewestMailbox, Seqlock, ...) and notify after
/// publishing it. Besides the semaphore, notify() release-increments an atomic counter that a
/// successful wait acquires, so a notify happens-before the wait it ends in the C++ memory
/// model as well (ThreadSanitizer does not intercept sem_clockwait).
///
/// Threading: notify() from any number of threads and from signal handlers; wait_until(),
/// wait_for() and drain() from one waiter thread; notifications() from anywhere.
#pragma once

#include <semaphore.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <ctime>
#include <system_error>

#include "wallar/core/time.hpp"

namespace wallar::firmware {

class Wakeup {
 public:
  /// Throws std::system_error if the semaphore cannot be initialised.
  Wakeup() {
    if (sem_init(&sem_, 0, 0) != 0) {
      throw std::system_error(errno, std::generic_category(), "Wakeup: sem_init");
    }
  }
  ~Wakeup() { sem_destroy(&sem_); }
  Wakeup(const Wakeup&) = delete;
  Wakeup& operator=(const Wakeup&) = delete;

  /// Wakes the waiter (now, or its next wait). Never blocks; async-signal-safe. Beyond
  /// SEM_VALUE_MAX pending notifications further ones are dropped (the waiter has plenty).
  void notify() noexcept {
    const int saved_errno = errno;  // a signal handler must leave errno as it found it
    notified_.fetch_add(1, std::memory_order_release);
    sem_post(&sem_);
    errno = saved_errno;
  }

  /// Sleeps until notified (true) or until CLOCK_MONOTONIC reaches `deadline_ns` (false).
  /// Returns at once when a notification is pending. Throws std::system_error on an
  /// unexpected semaphore error.
  bool wait_until(TimeNs deadline_ns) {
    const timespec ts = ns_to_timespec(deadline_ns < 0 ? 0 : deadline_ns);
    for (;;) {
      if (sem_clockwait(&sem_, CLOCK_MONOTONIC, &ts) == 0) {
        (void)notified_.load(std::memory_order_acquire);
        return true;
      }
      if (errno == ETIMEDOUT) return false;
      if (errno != EINTR) {
        throw std::system_error(errno, std::generic_category(), "Wakeup: sem_clockwait");
      }
    }
  }

  /// wait_until(now + timeout_ns); a timeout <= 0 only takes a pending notification.
  bool wait_for(DurationNs timeout_ns) {
    return wait_until(monotonic_now_ns() + (timeout_ns > 0 ? timeout_ns : 0));
  }

  /// Forgets all pending notifications.
  void drain() noexcept {
    for (;;) {
      if (sem_trywait(&sem_) == 0) continue;
      if (errno != EINTR) break;  // EAGAIN: none left
    }
    (void)notified_.load(std::memory_order_acquire);
  }

  /// notify() calls so far.
  [[nodiscard]] std::uint64_t notifications() const {
    return notified_.load(std::memory_order_relaxed);
  }

 private:
  sem_t sem_{};
  std::atomic<std::uint64_t> notified_{0};
};

}  // namespace wallar::firmware
