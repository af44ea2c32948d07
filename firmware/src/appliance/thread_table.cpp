// SPDX-License-Identifier: Apache-2.0
/// @file thread_table.cpp
/// @brief The appliance's thread table.
#include "wallar/firmware/appliance/thread_table.hpp"

#include <stdexcept>
#include <string>
#include <string_view>

namespace wallar::firmware {
namespace {

// The renderer stays SCHED_OTHER: Mesa's llvmpipe starts worker threads that would inherit a
// real-time policy and starve the rest on a small board. The supervisor (the main thread, for
// its loop only: ScopedThreadPriority) is above every worker but the IMU: it wakes at 10 Hz
// for microseconds, and the watchdog's keep-alives must not wait for busy workers.
constexpr std::size_t kMiB = 1024 * 1024;
constexpr ThreadTableEntry kThreadTable[] = {
    {"imu", 80, -1, 1 * kMiB, "IMU driver: FIFO, time stamps", false},
    {"capture", 70, -1, 1 * kMiB, "V4L2 capture and stereo pairing", false},
    {"replay", 70, -1, 2 * kMiB, "recording played as the sensors", false},
    {"push", 70, -1, 1 * kMiB, "pushed samples (VIT library) merged and paired", false},
    {"tracking", 60, -1, 4 * kMiB, "IMU filter, tracker, degraded modes", false},
    {"mapping", 0, -1, 8 * kMiB, "key-frames, bundle adjustment", false},
    {"reconstruct", 0, -1, 4 * kMiB, "walls, floor, ceiling", false},
    {"render", 0, -1, 4 * kMiB, "headset view (EGL)", false},
    {"supervisor", 75, -1, 0, "health, stop, stats, watchdog (main thread)", false},
    {"log", 0, -1, 256 * 1024, "log records formatted and written", false},
    {"live", 0, -1, 1 * kMiB, "live server: encodes for Foxglove (--live)", false},
    {"client", 0, -1, 1 * kMiB, "client API: planes and tracking state to apps (client:)", false},
};

}  // namespace

std::span<const ThreadTableEntry> thread_table() { return kThreadTable; }

ThreadTableEntry thread_table_entry(const char* name, const BoardConfig* board) {
  for (const ThreadTableEntry& e : kThreadTable) {
    if (std::string_view(e.name) != name) continue;
    ThreadTableEntry out = e;
    if (board != nullptr) {
      for (const ThreadPlacementConfig& t : board->threads) {
        if (t.name != name) continue;
        if (t.priority) out.priority = *t.priority;
        if (t.cpu) out.cpu = *t.cpu;
        if (t.policy == ThreadPolicy::kOther) out.priority = 0;
        if (t.policy) out.round_robin = *t.policy == ThreadPolicy::kRoundRobin;
      }
    }
    return out;
  }
  throw std::logic_error(std::string("thread table has no ") + name);
}

ThreadSpec thread_spec(const char* name, bool realtime, const BoardConfig* board) {
  const ThreadTableEntry e = thread_table_entry(name, board);
  ThreadSpec s;
  s.name = e.name;
  s.priority = realtime ? e.priority : 0;
  s.cpu = e.cpu;
  s.stack_bytes = e.stack_bytes;
  s.round_robin = e.round_robin;
  return s;
}

}  // namespace wallar::firmware
