// SPDX-License-Identifier: Apache-2.0
/// @file test_log_ring.cpp
/// @brief The log ring the fixed-rate threads post to: records formatted by the log thread as
/// printf would have, nothing lost or reordered per producer under four concurrent producers,
/// a full ring dropping and counting, and the log thread's rate limit saying what it held back.
#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <mutex>
#include <thread>
#include <vector>

#include "wallar/firmware/log_ring.hpp"

namespace wallar::firmware {
namespace {

std::string one(LogRing& ring) {
  LogRecord r;
  EXPECT_TRUE(ring.pop(r));
  return format_log_record(r);
}

TEST(LogRing, RecordsAreFormattedAsPrintfWouldHave) {
  LogRing ring(8);
  ring.post("t=%.3f s: %s", {1.23456, "camera lost"});
  ring.post("%s thread stalled (no progress for %g s): watchdog withheld", {"render", 2.0});
  ring.post("display lost: %s; re-opening every %lld ms", {LogArg::copied(), 500LL},
            "flip timed out");
  ring.post("%s: %s (%s%s%s); %s",
            {LogArg::copied(), "recovering", "device gone", ": ", LogArg::error(ENODEV), "x"},
            "left camera (/dev/video0)");
  ring.post("%d%% of %u, 0x%04x, %5.1f|%-4s|", {42, 7u, 255, 3.14159, "ab"});
  ring.post("too few: %d %s", {1});
  EXPECT_EQ(one(ring), "t=1.235 s: camera lost");
  EXPECT_EQ(one(ring), "render thread stalled (no progress for 2 s): watchdog withheld");
  EXPECT_EQ(one(ring), "display lost: flip timed out; re-opening every 500 ms");
  EXPECT_EQ(one(ring), std::string("left camera (/dev/video0): recovering (device gone: ") +
                           std::strerror(ENODEV) + "); x");
  EXPECT_EQ(one(ring), "42% of 7, 0x00ff,   3.1|ab  |");
  EXPECT_EQ(one(ring), "too few: 1 ?");
  LogRecord r;
  EXPECT_FALSE(ring.pop(r));
  // A copied string is cut at the record's size, never overrun.
  const std::string long_text(500, 'x');
  ring.post("%s", {LogArg::copied()}, long_text.c_str());
  EXPECT_EQ(one(ring), std::string(LogRecord::kCopiedChars, 'x'));
}

TEST(LogRing, FourProducersLoseNothingAndKeepTheirOrder) {
  LogRing ring(1024);
  constexpr int kPerProducer = 5000;
  std::vector<std::thread> producers;
  for (int p = 0; p < 4; ++p) {
    producers.emplace_back([&ring, p] {
      for (int i = 0; i < kPerProducer; ++i) {
        while (!ring.post("%d %d", {p, i})) std::this_thread::yield();  // full: the test waits
      }
    });
  }
  std::vector<int> next(4, 0);
  int received = 0;
  LogRecord r;
  while (received < 4 * kPerProducer) {
    if (!ring.pop(r)) {
      std::this_thread::yield();
      continue;
    }
    const auto p = static_cast<std::size_t>(r.args[0].i);
    ASSERT_LT(p, 4u);
    ASSERT_EQ(r.args[1].i, next[p]) << "producer " << p << " out of order";
    ++next[p];
    ++received;
  }
  for (std::thread& t : producers) t.join();
  EXPECT_FALSE(ring.pop(r));
  for (int n : next) EXPECT_EQ(n, kPerProducer);
}

TEST(LogRing, AFullRingDropsAndCountsAndTheThreadSaysSo) {
  LogRing ring(4);
  for (int i = 0; i < 6; ++i) ring.post("line %d", {i});
  EXPECT_EQ(ring.dropped(), 2u);
  std::vector<std::string> lines;
  std::mutex m;
  {
    LogThread thread(
        ring,
        [&](const std::string& line) {
          const std::lock_guard lock(m);
          lines.push_back(line);
        },
        ThreadSpec{"log", 0, -1, 0}, LogThread::Options{});
    thread.stop();
  }
  ASSERT_EQ(lines.size(), 5u);
  EXPECT_EQ(lines[0], "line 0");
  EXPECT_EQ(lines[3], "line 3");
  EXPECT_EQ(lines[4], "(2 log lines lost: the log ring was full)");
}

// A flapping device must not fill the journal: a burst, then the steady rate; what was held
// back is said in one line.
TEST(LogRing, TheLogThreadHoldsBackWhatExceedsItsRate) {
  LogRing ring(256);
  std::vector<std::string> lines;
  std::mutex m;
  LogThread::Options o;
  o.burst = 10;
  o.per_s = 0.001;  // no refill within the test
  LogThread thread(
      ring,
      [&](const std::string& line) {
        const std::lock_guard lock(m);
        lines.push_back(line);
      },
      ThreadSpec{"log", 0, -1, 0}, o);
  for (int i = 0; i < 50; ++i) ring.post("flap %d", {i});
  thread.stop();
  ASSERT_EQ(lines.size(), 11u);
  EXPECT_EQ(lines[9], "flap 9");
  EXPECT_EQ(lines[10], "(40 log lines held back)");
  EXPECT_EQ(thread.suppressed(), 40u);
}

// The SIGUSR1 stats table: the supervisor (SCHED_FIFO) only sets a flag; the log thread
// formats and writes the report, once per request, and not after it was withdrawn.
TEST(LogRing, AReportIsMadeOnTheLogThreadOncePerRequest) {
  LogRing ring(16);
  LogThread thread(ring, [](const std::string&) {}, ThreadSpec{"log", 0, -1, 0}, {});
  std::atomic<bool> request{false};
  std::mutex m;
  std::vector<std::string> out;
  std::vector<std::thread::id> made_on;
  thread.set_report(
      &request,
      [&] {
        const std::lock_guard lock(m);
        made_on.push_back(std::this_thread::get_id());
        return "table " + std::to_string(made_on.size());
      },
      [&](const std::string& t) {
        const std::lock_guard lock(m);
        out.push_back(t);
      });
  const auto wait_for = [&](std::size_t n) {
    for (int i = 0; i < 200; ++i) {
      {
        const std::lock_guard lock(m);
        if (out.size() >= n) return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  };
  request.store(true);
  wait_for(1);
  std::this_thread::sleep_for(std::chrono::milliseconds(250));  // two more wake-ups
  {
    const std::lock_guard lock(m);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_EQ(out[0], "table 1");
    EXPECT_NE(made_on[0], std::this_thread::get_id());
  }
  EXPECT_FALSE(request.load());
  request.store(true);
  wait_for(2);
  thread.set_report(nullptr, {}, {});
  request.store(true);
  std::this_thread::sleep_for(std::chrono::milliseconds(250));
  thread.stop();
  const std::lock_guard lock(m);
  EXPECT_EQ(out.size(), 2u);
  EXPECT_TRUE(request.load());  // withdrawn: nobody takes the request
}

}  // namespace
}  // namespace wallar::firmware
