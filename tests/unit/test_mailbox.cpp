// SPDX-License-Identifier: Apache-2.0
/// @file test_mailbox.cpp
/// @brief The newest-only mailbox: single-thread semantics, frames released, and a two-thread
/// stress test (values only move forward, nothing torn, counts add up); run under TSan in CI.
#include <gtest/gtest.h>

#include <thread>

#include "wallar/core/mailbox.hpp"
#include "wallar/core/stereo_frame.hpp"

namespace wallar::test {
namespace {

TEST(NewestMailbox, HandsOutOnlyTheNewestAndCountsTheRest) {
  NewestMailbox<int> box;
  int v = 0;
  EXPECT_FALSE(box.take(v));
  box.post(1);
  box.post(2);
  box.post(3);
  ASSERT_TRUE(box.take(v));
  EXPECT_EQ(v, 3);
  EXPECT_FALSE(box.take(v));
  EXPECT_EQ(box.overwritten(), 2u);
  box.post(4);
  ASSERT_TRUE(box.take(v));
  EXPECT_EQ(v, 4);
  EXPECT_EQ(box.overwritten(), 2u);
}

TEST(NewestMailbox, OverwrittenFramesReleaseTheirBuffersAtTheNextPost) {
  NewestMailbox<StereoFrame> box;
  StereoFrame a;
  a.left.image = Image::allocate(4, 4, PixelFormat::kGray8);
  const Image watch = a.left.image;
  box.post(a);
  a = StereoFrame{};
  EXPECT_EQ(watch.use_count(), 2);  // the watcher and the mailbox
  StereoFrame b;
  b.sequence = 1;
  box.post(b);  // a is overwritten, never taken
  EXPECT_EQ(watch.use_count(), 1);
  StereoFrame out;
  ASSERT_TRUE(box.take(out));
  EXPECT_EQ(out.sequence, 1u);
}

struct Payload {
  std::uint64_t seq = 0;
  std::uint64_t check = 0;  // ~seq: a torn copy would not match
};

TEST(NewestMailbox, TwoThreadsSeeMonotonicUntornValues) {
  NewestMailbox<Payload> box;
  constexpr std::uint64_t kPosts = 200000;
  std::uint64_t taken = 0, last = 0;
  bool ok = true;
  std::thread consumer([&] {
    Payload p;
    while (last < kPosts) {
      if (!box.take(p)) continue;
      if (p.check != ~p.seq || p.seq <= last) ok = false;
      last = p.seq;
      ++taken;
    }
  });
  for (std::uint64_t i = 1; i <= kPosts; ++i) box.post(Payload{i, ~i});
  consumer.join();
  EXPECT_TRUE(ok);
  EXPECT_EQ(last, kPosts);  // the newest value always arrives
  EXPECT_EQ(taken + box.overwritten(), kPosts);
}

}  // namespace
}  // namespace wallar::test
