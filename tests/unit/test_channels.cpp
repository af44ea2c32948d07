// SPDX-License-Identifier: Apache-2.0
/// @file test_channels.cpp
/// @brief Seqlock and TripleBuffer: single-thread semantics, and multi-thread stress tests
/// (every value read is whole, values only move forward, the last one arrives); run under
/// TSan in CI.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <thread>
#include <vector>

#include "wallar/core/seqlock.hpp"
#include "wallar/core/triple_buffer.hpp"

namespace wallar::test {
namespace {

bool channels_short_run() { return std::getenv("WALLAR_SHORT_TESTS") != nullptr; }

/// Nine words that a torn copy would not keep equal.
struct SeqlockPayload {
  std::array<std::uint64_t, 8> words{};
  std::uint64_t counter = 0;

  static SeqlockPayload of(std::uint64_t k) {
    SeqlockPayload p;
    p.words.fill(k);
    p.counter = k;
    return p;
  }
  [[nodiscard]] bool whole() const {
    for (const std::uint64_t w : words) {
      if (w != counter) return false;
    }
    return true;
  }
};

TEST(Seqlock, StoresLoadsAndCountsVersions) {
  Seqlock<SeqlockPayload> lock(SeqlockPayload::of(7));
  EXPECT_EQ(lock.version(), 0u);
  EXPECT_EQ(lock.load().counter, 7u);
  lock.store(SeqlockPayload::of(8));
  lock.store(SeqlockPayload::of(9));
  EXPECT_EQ(lock.version(), 2u);
  SeqlockPayload got;
  ASSERT_TRUE(lock.try_load(got));  // no store in progress: the one attempt succeeds
  EXPECT_TRUE(got.whole());
  EXPECT_EQ(got.counter, 9u);
}

TEST(Seqlock, OddSizedValuesRoundTrip) {
  struct Odd {
    char c[13];
  };
  Seqlock<Odd> lock;
  Odd in{};
  for (int i = 0; i < 13; ++i) in.c[i] = static_cast<char>('a' + i);
  lock.store(in);
  const Odd out = lock.load();
  for (int i = 0; i < 13; ++i) EXPECT_EQ(out.c[i], in.c[i]);
}

TEST(Seqlock, ReadersSeeWholeValuesThatNeverGoBackwards) {
  const std::uint64_t stores = channels_short_run() ? 20'000 : 200'000;
  Seqlock<SeqlockPayload> lock;
  std::atomic<bool> writer_done{false};
  std::atomic<int> readers_ready{0};

  struct ReaderResult {
    std::uint64_t reads = 0;
    std::uint64_t torn = 0;
    std::uint64_t backwards = 0;
    std::uint64_t failed_attempts = 0;  // try_load only
    std::uint64_t last = 0;
  };
  std::array<ReaderResult, 2> results{};
  const auto read_loop = [&](ReaderResult& r, bool use_try_load) {
    readers_ready.fetch_add(1);
    SeqlockPayload p;
    for (;;) {
      const bool done = writer_done.load(std::memory_order_acquire);
      if (use_try_load) {
        if (!lock.try_load(p)) {
          ++r.failed_attempts;
          continue;
        }
      } else {
        p = lock.load();
      }
      ++r.reads;
      if (!p.whole()) ++r.torn;
      if (p.counter < r.last) ++r.backwards;
      r.last = p.counter;
      if (done) break;  // this read started after the writer finished: it saw the last store
    }
  };
  std::thread reader_load([&] { read_loop(results[0], false); });
  std::thread reader_try([&] { read_loop(results[1], true); });
  while (readers_ready.load() < 2) std::this_thread::yield();
  for (std::uint64_t k = 1; k <= stores; ++k) lock.store(SeqlockPayload::of(k));
  writer_done.store(true, std::memory_order_release);
  reader_load.join();
  reader_try.join();

  for (const ReaderResult& r : results) {
    EXPECT_GT(r.reads, 0u);
    EXPECT_EQ(r.torn, 0u);
    EXPECT_EQ(r.backwards, 0u);
    EXPECT_EQ(r.last, stores);
  }
  EXPECT_EQ(lock.version(), stores);
  EXPECT_EQ(lock.load().counter, stores);
}

TEST(TripleBuffer, RefreshTakesOnlyNewValuesAndFrontStaysPut) {
  int made = 0;
  TripleBuffer<int> buf([&made] { return 100 + made++; });
  EXPECT_EQ(made, 3);
  EXPECT_EQ(buf.front(), 101);  // slot 1 until the first refresh
  EXPECT_FALSE(buf.refresh());  // nothing published
  EXPECT_EQ(buf.front(), 101);

  buf.back() = 1;
  buf.publish();
  EXPECT_EQ(buf.front(), 101);  // unchanged until refresh
  ASSERT_TRUE(buf.refresh());
  EXPECT_EQ(buf.front(), 1);
  const int* held = &buf.front();
  EXPECT_FALSE(buf.refresh());  // nothing new: the value is kept, not consumed
  EXPECT_EQ(buf.front(), 1);
  EXPECT_EQ(&buf.front(), held);

  for (int k = 2; k <= 4; ++k) {
    EXPECT_NE(&buf.back(), &buf.front());  // the writer never gets the reader's slot
    buf.back() = k;
    buf.publish();
  }
  EXPECT_EQ(buf.front(), 1);
  ASSERT_TRUE(buf.refresh());
  EXPECT_EQ(buf.front(), 4);  // the newest only
  EXPECT_FALSE(buf.refresh());
  EXPECT_EQ(buf.published(), 4u);
  EXPECT_NE(buf.back(), 4);  // the writer's slot holds an older value, not the one published
}

TEST(TripleBuffer, ReaderSeesWholeMonotonicSnapshotsAndTheLastOne) {
  constexpr std::size_t kLen = 256;
  const std::uint64_t publishes = channels_short_run() ? 5'000 : 50'000;
  TripleBuffer<std::vector<std::uint64_t>> buf([] { return std::vector<std::uint64_t>(kLen, 0); });
  std::atomic<bool> writer_done{false};
  std::atomic<bool> reader_ready{false};

  std::uint64_t refreshes = 0, torn = 0, not_newer = 0, wrong_size = 0, last = 0;
  std::thread reader([&] {
    reader_ready.store(true);
    const auto check = [&] {
      const std::vector<std::uint64_t>& v = buf.front();
      if (v.size() != kLen) {
        ++wrong_size;
        return;
      }
      for (const std::uint64_t x : v) {
        if (x != v[0]) {
          ++torn;
          break;
        }
      }
      if (v[0] <= last) ++not_newer;
      last = v[0];
    };
    while (!writer_done.load(std::memory_order_acquire)) {
      if (!buf.refresh()) continue;
      ++refreshes;
      check();
    }
    if (buf.refresh()) {  // the writer's last publish, unless already taken above
      ++refreshes;
      check();
    }
  });

  std::vector<const std::uint64_t*> storage;  // the slots' buffers the writer filled
  while (!reader_ready.load()) std::this_thread::yield();
  for (std::uint64_t k = 1; k <= publishes; ++k) {
    std::vector<std::uint64_t>& slot = buf.back();
    for (std::uint64_t& x : slot) x = k;  // overwrite every element, in place
    bool known = false;
    for (const std::uint64_t* p : storage) known = known || p == slot.data();
    if (!known) storage.push_back(slot.data());
    buf.publish();
  }
  writer_done.store(true, std::memory_order_release);
  reader.join();

  EXPECT_GT(refreshes, 0u);
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(not_newer, 0u);
  EXPECT_EQ(wrong_size, 0u);
  EXPECT_EQ(last, publishes);
  EXPECT_EQ(buf.front()[0], publishes);
  EXPECT_EQ(buf.published(), publishes);
  EXPECT_LE(storage.size(), 3u);  // no slot was ever reallocated
}

}  // namespace
}  // namespace wallar::test
