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

}  // namespace wallar::firmware
