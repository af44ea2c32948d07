// SPDX-License-Identifier: Apache-2.0
/// @file test_runtime.cpp
/// @brief The fixed-rate runtime: latency histogram against exact percentiles, the periodic
/// timer's deadline grid and miss counting, real-time threads (placement or a stated fallback,
/// name, CPU time, caught exceptions), memory locking, and the wake-up.
///
/// No assertion depends on the machine being idle: timing checks are counts or one-sided
/// bounds that a loaded CI machine, qemu or a sanitizer can only make easier to meet.
#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "wallar/core/time.hpp"
#include "wallar/firmware/latency_histogram.hpp"
#include "wallar/firmware/periodic.hpp"
#include "wallar/firmware/rt_thread.hpp"
#include "wallar/firmware/wakeup.hpp"

#if defined(WALLAR_SANITIZED)
#define WALLAR_RUNTIME_TEST_SANITIZED 1
#endif

namespace wallar::test {
namespace {

using firmware::LatencyHistogram;
using firmware::PeriodicTimer;
using firmware::RtThread;
using firmware::ThreadSpec;
using firmware::Wakeup;

/// The q-th value as LatencyHistogram defines it: the ceil(q * n)-th smallest (the smallest
/// for q = 0).
DurationNs exact_percentile(const std::vector<DurationNs>& sorted, double q) {
  const auto n = static_cast<double>(sorted.size());
  auto rank = static_cast<std::size_t>(std::ceil(q * n));
  rank = std::clamp<std::size_t>(rank, 1, sorted.size());
  return sorted[rank - 1];
}

/// Spins until this thread has used `cpu_ns` of CPU time (not wall time: a loaded machine
/// only makes it take longer).
void burn_cpu(DurationNs cpu_ns) {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  const DurationNs start_ns = ts.tv_sec * kNsPerS + ts.tv_nsec;
  volatile std::uint64_t sink = 0;
  for (;;) {
    for (int i = 0; i < 1000; ++i) sink = sink + static_cast<std::uint64_t>(i);
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    if (ts.tv_sec * kNsPerS + ts.tv_nsec - start_ns >= cpu_ns) return;
  }
}

TEST(LatencyHistogram, BinsCoverEveryValueWithinOneThirtySecond) {
  EXPECT_EQ(LatencyHistogram::bin_of(0), 0u);
  EXPECT_EQ(LatencyHistogram::bin_of(LatencyHistogram::kMinNs - 1), 0u);
  EXPECT_EQ(LatencyHistogram::bin_of(LatencyHistogram::kMinNs), 1u);
  EXPECT_EQ(LatencyHistogram::bin_of(LatencyHistogram::kTopNs), LatencyHistogram::kBins - 1);
  EXPECT_EQ(LatencyHistogram::bin_of(LatencyHistogram::kTopNs - 1), LatencyHistogram::kBins - 2);
  EXPECT_EQ(LatencyHistogram::bin_upper_ns(LatencyHistogram::kBins - 2),
            LatencyHistogram::kTopNs - 1);
  for (std::size_t b = 1; b + 1 < LatencyHistogram::kBins; ++b) {
    // Contiguous: each bin starts right after the previous one ends.
    const DurationNs lower = LatencyHistogram::bin_upper_ns(b - 1) + 1;
    const DurationNs upper = LatencyHistogram::bin_upper_ns(b);
    ASSERT_LT(lower, upper);
    ASSERT_EQ(LatencyHistogram::bin_of(lower), b);
    ASSERT_EQ(LatencyHistogram::bin_of(upper), b);
    ASSERT_LE(static_cast<double>(upper - lower), static_cast<double>(lower) / 32.0) << b;
  }
}

TEST(LatencyHistogram, PercentilesMatchTheSortedValuesWithinABin) {
  std::mt19937_64 rng(20240611);
  LatencyHistogram hist;
  std::vector<DurationNs> values;
  constexpr int kValues = 100'000;
  values.reserve(kValues);
  std::uint64_t sum = 0;
  for (int i = 0; i < kValues; ++i) {
    // Log-uniform over 2^8 .. 2^34 ns (256 ns .. 17 s) from integer arithmetic only: an
    // octave, then a position within it.
    const int octave = 8 + static_cast<int>(rng() % 26);
    const auto base = std::uint64_t{1} << octave;
    const auto v = static_cast<DurationNs>(base + rng() % base);
    values.push_back(v);
    sum += static_cast<std::uint64_t>(v);
    hist.record(v);
  }
  std::sort(values.begin(), values.end());

  EXPECT_EQ(hist.count(), static_cast<std::uint64_t>(kValues));
  EXPECT_EQ(hist.max_ns(), values.back());
  EXPECT_DOUBLE_EQ(hist.mean_ns(), static_cast<double>(sum) / kValues);
  for (const double q : {0.0, 0.001, 0.01, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99, 0.999, 1.0}) {
    const DurationNs exact = exact_percentile(values, q);
    const DurationNs got = hist.percentile_ns(q);
    EXPECT_GE(got, exact) << "q=" << q;
    if (exact < LatencyHistogram::kMinNs) {
      EXPECT_LT(got, LatencyHistogram::kMinNs) << "q=" << q;
    } else {
      EXPECT_LE(static_cast<double>(got), static_cast<double>(exact) * (1.0 + 1.0 / 32.0))
          << "q=" << q;
    }
  }
  EXPECT_EQ(hist.percentile_ns(1.0), values.back());  // capped at the max, exactly

  const firmware::LatencySummary s = hist.summary();
  EXPECT_EQ(s.count, static_cast<std::uint64_t>(kValues));
  EXPECT_DOUBLE_EQ(s.max_ms, static_cast<double>(values.back()) * 1e-6);
  EXPECT_DOUBLE_EQ(s.p50_ms, static_cast<double>(hist.percentile_ns(0.5)) * 1e-6);
  EXPECT_DOUBLE_EQ(s.p99_ms, static_cast<double>(hist.percentile_ns(0.99)) * 1e-6);
  EXPECT_DOUBLE_EQ(s.mean_ms, hist.mean_ns() * 1e-6);
}

TEST(LatencyHistogram, EmptyClampedAndReset) {
  LatencyHistogram hist;
  EXPECT_EQ(hist.count(), 0u);
  EXPECT_EQ(hist.percentile_ns(0.5), 0);
  EXPECT_EQ(hist.max_ns(), 0);
  EXPECT_EQ(hist.mean_ns(), 0.0);
  EXPECT_EQ(hist.summary().count, 0u);

  hist.record(-5);  // a clock step backwards: counts as 0
  EXPECT_EQ(hist.count(), 1u);
  EXPECT_EQ(hist.max_ns(), 0);
  EXPECT_EQ(hist.percentile_ns(0.5), 0);

  const DurationNs stall_ns = 1000 * kNsPerS;  // above the top bin: the overflow bin
  hist.record(stall_ns);
  EXPECT_EQ(hist.max_ns(), stall_ns);
  EXPECT_EQ(hist.percentile_ns(1.0), stall_ns);
  // The 0 sits in the sub-microsecond bin, reported by its upper edge now that max is larger.
  constexpr DurationNs kSubUsEdgeNs = LatencyHistogram::kMinNs - 1;
  EXPECT_EQ(hist.percentile_ns(0.0), kSubUsEdgeNs);
  EXPECT_EQ(hist.percentile_ns(0.5), kSubUsEdgeNs);
  EXPECT_EQ(hist.percentile_ns(-1.0), kSubUsEdgeNs);  // q clamped
  EXPECT_EQ(hist.percentile_ns(2.0), stall_ns);
  EXPECT_EQ(hist.percentile_ns(std::numeric_limits<double>::quiet_NaN()), kSubUsEdgeNs);

  hist.record(std::numeric_limits<DurationNs>::max());
  EXPECT_EQ(hist.max_ns(), LatencyHistogram::kMaxValueNs);
  EXPECT_DOUBLE_EQ(hist.mean_ns(),
                   static_cast<double>(stall_ns + LatencyHistogram::kMaxValueNs) / 3.0);

  hist.reset();
  EXPECT_EQ(hist.count(), 0u);
  EXPECT_EQ(hist.max_ns(), 0);
  EXPECT_EQ(hist.percentile_ns(1.0), 0);
  hist.record(5 * kNsPerMs);
  EXPECT_EQ(hist.count(), 1u);
  EXPECT_EQ(hist.percentile_ns(0.5), 5 * kNsPerMs);  // the bin edge capped at the max
}

TEST(PeriodicTimer, DeadlinesStayOnTheGrid) {
  constexpr DurationNs kPeriodNs = 2 * kNsPerMs;
  const TimeNs start_ns = monotonic_now_ns();
  PeriodicTimer timer(kPeriodNs, start_ns);
  EXPECT_EQ(timer.next_deadline_ns(), start_ns + kPeriodNs);
  for (int k = 1; k <= 20; ++k) {
    const std::uint64_t misses_before = timer.misses();
    const TimeNs deadline_ns = timer.wait();
    // On an idle machine misses() stays 0 and this is start + k * period; a loaded one may
    // skip deadlines, but only whole periods, so the grid holds either way.
    EXPECT_EQ(deadline_ns, start_ns + (k + static_cast<DurationNs>(misses_before)) * kPeriodNs);
    EXPECT_GE(monotonic_now_ns(), deadline_ns);  // never wakes early
    EXPECT_GE(timer.lateness_ns(), 0);
    EXPECT_GT(timer.next_deadline_ns(), deadline_ns);
  }
  EXPECT_EQ(timer.wakeups(), 20u);
  EXPECT_GE(timer.max_lateness_ns(), timer.lateness_ns());
  EXPECT_THROW(PeriodicTimer(0), std::invalid_argument);
}

TEST(PeriodicTimer, AnOverrunIsCountedAndNotCaughtUp) {
  constexpr DurationNs kPeriodNs = 2 * kNsPerMs;
  const TimeNs start_ns = monotonic_now_ns();
  PeriodicTimer timer(kPeriodNs, start_ns);
  const TimeNs first_ns = timer.wait();
  EXPECT_EQ(first_ns, start_ns + kPeriodNs);
  // 0 on an idle machine; a loaded one may already have woken a period late here.
  const std::uint64_t misses_first = timer.misses();
  const TimeNs following_ns = timer.next_deadline_ns();
  EXPECT_EQ(following_ns, first_ns + (static_cast<DurationNs>(misses_first) + 1) * kPeriodNs);

  // The loop overruns: the following deadline is at most a period after the wake-up, so it
  // is 8+ ms in the past when wait() is called again.
  std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const TimeNs late_ns = timer.wait();
  EXPECT_EQ(late_ns, following_ns);  // returns at once, for the deadline it was due for
  const std::uint64_t lost = timer.misses() - misses_first;
  EXPECT_GE(lost, 3u);
  EXPECT_GE(timer.lateness_ns(), 3 * kPeriodNs);
  // No backlog: the next deadline lies after the moment wait() woke (deadline + lateness)...
  EXPECT_GT(timer.next_deadline_ns(), late_ns + timer.lateness_ns());
  // ... and is the first such one on the grid.
  EXPECT_EQ(timer.next_deadline_ns(), late_ns + (static_cast<DurationNs>(lost) + 1) * kPeriodNs);
  EXPECT_LE(timer.next_deadline_ns() - kPeriodNs, late_ns + timer.lateness_ns());
  EXPECT_EQ((timer.next_deadline_ns() - start_ns) % kPeriodNs, 0);

  const TimeNs next_expected_ns = timer.next_deadline_ns();
  const TimeNs next_ns = timer.wait();  // sleeps again instead of bursting
  EXPECT_EQ(next_ns, next_expected_ns);
  EXPECT_GE(monotonic_now_ns(), next_ns);
  EXPECT_EQ(timer.wakeups(), 3u);
  EXPECT_GE(timer.max_lateness_ns(), 3 * kPeriodNs);
}

TEST(RtThread, RunsTheBodyUnderItsName) {
  std::atomic<bool> ran{false};
  std::string name_seen;
  RtThread thread(ThreadSpec{.name = "wallar-test-a-very-long-name"}, [&] {
    char buf[32] = {};
    pthread_getname_np(pthread_self(), buf, sizeof(buf));
    name_seen = buf;
    ran = true;
  });
  EXPECT_TRUE(thread.joinable());
  EXPECT_EQ(thread.spec().name, "wallar-test-a-very-long-name");
  EXPECT_TRUE(thread.placement().fallback.empty()) << thread.placement().fallback;
  EXPECT_FALSE(thread.placement().fifo);
  EXPECT_GT(thread.placement().stack_bytes, 0u);
  thread.join();
  EXPECT_FALSE(thread.joinable());
  EXPECT_TRUE(ran);
  EXPECT_TRUE(thread.finished());
  EXPECT_EQ(name_seen, "wallar-test-a-v");  // the first 15 characters
  EXPECT_FALSE(thread.failed());
  EXPECT_EQ(thread.error(), "");
  EXPECT_THROW(thread.join(), std::system_error);
}

TEST(RtThread, ReportsItsCpuTimeAfterJoin) {
  constexpr DurationNs kBusyNs = 5 * kNsPerMs;
  std::atomic<bool> go{false};
  RtThread thread(ThreadSpec{.name = "busy"}, [&] {
    while (!go.load()) std::this_thread::yield();
    burn_cpu(kBusyNs);
  });
  EXPECT_GE(thread.cpu_time_ns(), 0);  // live reading while it runs
  go = true;
  thread.join();
  EXPECT_GE(thread.cpu_time_ns(), kBusyNs);
  EXPECT_EQ(thread.cpu_time_ns(), thread.cpu_time_ns());  // final, stable after join
}

TEST(RtThread, FifoPriorityIsAppliedOrExplained) {
  int policy_seen = -1;
  RtThread thread(ThreadSpec{.name = "fifo80", .priority = 80, .stack_bytes = 256 * 1024}, [&] {
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy_seen, &param);
  });
  thread.join();
  const firmware::ThreadPlacement& p = thread.placement();
  // Either it runs SCHED_FIFO (root, CAP_SYS_NICE or RLIMIT_RTPRIO) or it says why not.
  EXPECT_NE(p.fifo, !p.fallback.empty()) << p.fallback;
  if (p.fifo) {
    EXPECT_EQ(p.priority, 80);
    EXPECT_EQ(policy_seen, SCHED_FIFO);
  } else {
    EXPECT_EQ(p.priority, 0);
    EXPECT_NE(policy_seen, SCHED_FIFO);
    EXPECT_NE(p.fallback.find("SCHED_FIFO 80"), std::string::npos) << p.fallback;
  }
  EXPECT_GE(p.stack_bytes, 256u * 1024u);
}

TEST(RtThread, RoundRobinIsAppliedOrExplained) {
  // A board's `policy: rr`: SCHED_RR at the priority, or the reason it could not be had.
  int policy_seen = -1;
  RtThread thread(ThreadSpec{.name = "rr40", .priority = 40, .round_robin = true}, [&] {
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy_seen, &param);
  });
  thread.join();
  const firmware::ThreadPlacement& p = thread.placement();
  EXPECT_NE(p.fifo, !p.fallback.empty()) << p.fallback;
  if (p.fifo) {
    EXPECT_TRUE(p.round_robin);
    EXPECT_EQ(p.priority, 40);
    EXPECT_EQ(policy_seen, SCHED_RR);
  } else {
    EXPECT_FALSE(p.round_robin);
    EXPECT_NE(p.fallback.find("SCHED_RR 40"), std::string::npos) << p.fallback;
  }
}

// The supervisor's loop on the main thread: SCHED_FIFO while the object lives, the thread's own
// policy again after it (on a thread of its own here, so the test runner keeps its policy).
TEST(ScopedThreadPriority, RaisesTheCallingThreadForItsScopeOrExplains) {
  int during = -1, during_priority = -1, after = -1;
  firmware::ThreadPlacement p;
  std::thread([&] {
    {
      const firmware::ScopedThreadPriority scoped(30);
      p = scoped.placement();
      sched_param param{};
      pthread_getschedparam(pthread_self(), &during, &param);
      during_priority = param.sched_priority;
    }
    sched_param param{};
    pthread_getschedparam(pthread_self(), &after, &param);
  }).join();
  EXPECT_NE(p.fifo, !p.fallback.empty()) << p.fallback;
  if (p.fifo) {
    EXPECT_EQ(during, SCHED_FIFO);
    EXPECT_EQ(during_priority, 30);
  } else {
    EXPECT_NE(during, SCHED_FIFO);
    EXPECT_NE(p.fallback.find("SCHED_FIFO 30"), std::string::npos) << p.fallback;
  }
  EXPECT_EQ(after, SCHED_OTHER);
  // Priority 0 leaves the thread as it is and says nothing.
  const firmware::ScopedThreadPriority none(0);
  EXPECT_FALSE(none.placement().fifo);
  EXPECT_TRUE(none.placement().fallback.empty());
}

TEST(RtThread, PinsToAnOnlineCpuAndSkipsAMissingOne) {
  int cpu_seen = -1;
  RtThread pinned(ThreadSpec{.name = "pin0", .cpu = 0}, [&] { cpu_seen = sched_getcpu(); });
  pinned.join();
  if (pinned.placement().cpu == 0) {
    EXPECT_EQ(cpu_seen, 0);
    EXPECT_TRUE(pinned.placement().fallback.empty()) << pinned.placement().fallback;
  } else {  // cpu 0 outside this process's cpuset
    EXPECT_FALSE(pinned.placement().fallback.empty());
  }

  RtThread nowhere(ThreadSpec{.name = "pin4096", .cpu = 4096}, [] {});
  nowhere.join();
  EXPECT_EQ(nowhere.placement().cpu, -1);
  EXPECT_NE(nowhere.placement().fallback.find("cpu 4096"), std::string::npos)
      << nowhere.placement().fallback;
}

TEST(RtThread, KeepsAnEscapedExceptionInsteadOfTerminating) {
  RtThread thrower(ThreadSpec{.name = "thrower"}, [] { throw std::runtime_error("boom"); });
  thrower.join();
  EXPECT_TRUE(thrower.failed());
  EXPECT_EQ(thrower.error(), "boom");
  EXPECT_TRUE(thrower.finished());

  RtThread odd(ThreadSpec{.name = "odd"}, [] { throw 42; });
  odd.join();
  EXPECT_TRUE(odd.failed());
  EXPECT_EQ(odd.error(), "unknown exception");
}

TEST(RtThread, MovesAndJoinsOnDestruction) {
  std::atomic<int> runs{0};
  {
    std::vector<RtThread> threads;
    for (int i = 0; i < 3; ++i) {
      threads.emplace_back(ThreadSpec{.name = "mover" + std::to_string(i)}, [&] { ++runs; });
    }
    RtThread moved(std::move(threads[0]));
    EXPECT_FALSE(threads[0].joinable());
    EXPECT_TRUE(moved.joinable());
    EXPECT_EQ(moved.spec().name, "mover0");
    threads[0] = std::move(moved);
    EXPECT_TRUE(threads[0].joinable());
  }  // destructors join
  EXPECT_EQ(runs.load(), 3);
}

TEST(RtThread, RejectsBadSpecs) {
  EXPECT_THROW(RtThread(ThreadSpec{.name = "empty"}, nullptr), std::invalid_argument);
  EXPECT_THROW(RtThread(ThreadSpec{.name = "prio", .priority = 100}, [] {}), std::invalid_argument);
  EXPECT_THROW(RtThread(ThreadSpec{.name = "prio", .priority = -1}, [] {}), std::invalid_argument);
}

TEST(LockMemory, LocksOrSaysWhy) {
#ifdef WALLAR_RUNTIME_TEST_SANITIZED
  GTEST_SKIP() << "mlockall would pin the sanitizer's shadow memory";
#else
  const firmware::MemoryLock lock = firmware::lock_memory();
  EXPECT_NE(lock.locked, !lock.warning.empty()) << lock.warning;
  if (lock.locked) {
    munlockall();  // do not keep the rest of the test run locked
  } else {
    EXPECT_EQ(lock.warning.rfind("mlockall: ", 0), 0u) << lock.warning;
    EXPECT_EQ(lock.warning.find('\n'), std::string::npos);
  }
#endif
}

TEST(Wakeup, TimesOutWithoutANotification) {
  Wakeup wakeup;
  const TimeNs before_ns = monotonic_now_ns();
  EXPECT_FALSE(wakeup.wait_for(5 * kNsPerMs));
  EXPECT_GE(monotonic_now_ns() - before_ns, 5 * kNsPerMs);  // slept to the deadline
  EXPECT_FALSE(wakeup.wait_for(0));
  EXPECT_FALSE(wakeup.wait_until(0));  // a deadline in the past
}

TEST(Wakeup, ANotifyFromAnotherThreadWakesTheWaiter) {
  Wakeup wakeup;
  int payload = 0;  // plain data, ordered by the notify (TSan checks this)
  std::thread notifier([&] {
    payload = 42;
    wakeup.notify();
  });
  EXPECT_TRUE(wakeup.wait_for(60 * kNsPerS));  // generous: only a failure waits this long
  EXPECT_EQ(payload, 42);
  notifier.join();
  EXPECT_EQ(wakeup.notifications(), 1u);
}

TEST(Wakeup, NotificationsCountAndDrain) {
  Wakeup wakeup;
  wakeup.notify();
  wakeup.notify();
  EXPECT_TRUE(wakeup.wait_for(0));
  EXPECT_TRUE(wakeup.wait_for(0));
  EXPECT_FALSE(wakeup.wait_for(0));
  for (int i = 0; i < 5; ++i) wakeup.notify();
  wakeup.drain();
  EXPECT_FALSE(wakeup.wait_for(kNsPerMs));
  EXPECT_EQ(wakeup.notifications(), 7u);
}

}  // namespace
}  // namespace wallar::test
