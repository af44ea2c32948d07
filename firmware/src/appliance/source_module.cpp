// SPDX-License-Identifier: Apache-2.0
/// @file source_module.cpp
/// @brief What every source module shares.
#include "wallar/firmware/appliance/source_module.hpp"

#include <time.h>

namespace wallar::firmware {

bool wait_flag(const std::atomic<bool>& flag, DurationNs timeout_ns) {
  const TimeNs until = monotonic_now_ns() + timeout_ns;
  while (!flag.load(std::memory_order_acquire)) {
    if (monotonic_now_ns() >= until) return false;
    const timespec ts{0, 5 * kNsPerMs};
    nanosleep(&ts, nullptr);
  }
  return true;
}

bool join_source_thread(RtThread* thread, const std::atomic<bool>& done, DurationNs timeout_ns) {
  if (thread == nullptr) return true;
  if (!wait_flag(done, timeout_ns) && !thread->failed()) return false;
  thread->join();
  return true;
}

std::exception_ptr source_thread_error(const RtThread* thread) {
  return thread != nullptr && thread->failed() ? thread->exception() : std::exception_ptr();
}

}  // namespace wallar::firmware
