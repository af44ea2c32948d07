// SPDX-License-Identifier: Apache-2.0
/// @file source_runner.cpp
/// @brief Source thread with stop, time limit and exception hand-back.
#include "wallar/firmware/source_runner.hpp"

#include <pthread.h>

#include <exception>
#include <thread>

namespace wallar::firmware {

source::ReplayStats run_replay(const recording::EurocRecording& rec,
                               const source::ReplayOptions& options, source::SensorSink& sink,
                               const std::atomic<bool>& stop, DurationNs max_duration_ns) {
  source::ReplaySource replay(rec, options);
  std::atomic<bool> source_stop{false};
  std::atomic<bool> done{false};
  source::ReplayStats stats;
  std::exception_ptr error;

  std::thread worker([&] {
    pthread_setname_np(pthread_self(), "replay");
    try {
      stats = replay.run(sink, source_stop);
    } catch (...) {
      error = std::current_exception();
    }
    done.store(true, std::memory_order_release);
  });

  const TimeNs deadline = max_duration_ns > 0 ? monotonic_now_ns() + max_duration_ns : 0;
  while (!done.load(std::memory_order_acquire)) {
    if (stop.load(std::memory_order_relaxed) || (deadline > 0 && monotonic_now_ns() >= deadline)) {
      source_stop.store(true, std::memory_order_relaxed);
    }
    const timespec ts = ns_to_timespec(10 * kNsPerMs);
    nanosleep(&ts, nullptr);
  }
  worker.join();
  if (error) std::rethrow_exception(error);
  return stats;
}

}  // namespace wallar::firmware
