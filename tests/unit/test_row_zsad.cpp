// SPDX-License-Identifier: Apache-2.0
// The stereo row search's SIMD kernel: exact agreement of every SIMD target with the scalar
// reference, and the integer cost against the zero-mean SAD's definition in floating point.
#include <hwy/targets.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "wallar/dsp/tracking/row_zsad.hpp"

namespace {

using wallar::dsp::row_zsad;
using wallar::dsp::row_zsad_scalar;

struct TestImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> px;
  const std::uint8_t* at(int x, int y) const {
    return px.data() + static_cast<std::ptrdiff_t>(y) * width + x;
  }
};

/// Texture with saturated patches (0 and 255 runs: the cost's extremes) and noise.
TestImage random_image(int width, int height, std::uint32_t seed) {
  std::mt19937 rng(seed);
  TestImage im{width, height, std::vector<std::uint8_t>(static_cast<std::size_t>(width * height))};
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::uint32_t r = rng();
      std::uint8_t v = static_cast<std::uint8_t>(r & 0xff);
      if ((x / 16 + y / 8) % 5 == 0) v = (r >> 8) % 2 == 0 ? 0 : 255;
      im.px[static_cast<std::size_t>(y * width + x)] = v;
    }
  }
  return im;
}

/// sum_k |(T_k - mean T) - (I_k - mean I)| / n in double: the definition.
double zsad_per_px(const TestImage& t, int tx, int ty, const TestImage& im, int x, int y, int hw) {
  const int n = (2 * hw + 1) * (2 * hw + 1);
  double mt = 0.0, mi = 0.0;
  for (int dy = -hw; dy <= hw; ++dy) {
    for (int dx = -hw; dx <= hw; ++dx) {
      mt += *t.at(tx + dx, ty + dy);
      mi += *im.at(x + dx, y + dy);
    }
  }
  mt /= n;
  mi /= n;
  double c = 0.0;
  for (int dy = -hw; dy <= hw; ++dy) {
    for (int dx = -hw; dx <= hw; ++dx) {
      c += std::abs((*t.at(tx + dx, ty + dy) - mt) - (*im.at(x + dx, y + dy) - mi));
    }
  }
  return c / n;
}

/// Every (hw, count, start) case: the kernel as dispatched now against the scalar reference.
int compare_with_scalar(const TestImage& left, const TestImage& right) {
  int cases = 0;
  std::mt19937 rng(7);
  for (int hw = 1; hw <= 5; ++hw) {
    for (int count : {1, 2, 7, 8, 15, 16, 17, 31, 33, 64, 100, 255, 512, 700}) {
      const int y = hw + static_cast<int>(rng() % static_cast<std::uint32_t>(left.height - 2 * hw));
      const int tx = hw + static_cast<int>(rng() % static_cast<std::uint32_t>(left.width - 2 * hw));
      const int x0 = hw + static_cast<int>(
                              rng() % static_cast<std::uint32_t>(right.width - 2 * hw - count + 1));
      std::vector<std::uint32_t> simd(static_cast<std::size_t>(count) + 1, 0xdeadbeef);
      std::vector<std::uint32_t> ref(static_cast<std::size_t>(count), 0);
      EXPECT_TRUE(row_zsad(left.at(tx, y), left.width, right.at(x0, y), right.width, hw, count,
                           simd.data()));
      EXPECT_TRUE(row_zsad_scalar(left.at(tx, y), left.width, right.at(x0, y), right.width, hw,
                                  count, ref.data()));
      for (int j = 0; j < count; ++j) {
        EXPECT_EQ(simd[static_cast<std::size_t>(j)], ref[static_cast<std::size_t>(j)])
            << "hw " << hw << " count " << count << " j " << j;
      }
      EXPECT_EQ(simd[static_cast<std::size_t>(count)], 0xdeadbeefu) << "wrote past the end";
      ++cases;
    }
  }
  return cases;
}

TEST(RowZsad, TheIntegerCostIsTheZeroMeanSadTimesNSquared) {
  const TestImage left = random_image(200, 40, 1), right = random_image(200, 40, 2);
  for (int hw = 1; hw <= 7; ++hw) {
    const int n = (2 * hw + 1) * (2 * hw + 1);
    const int count = 200 - 2 * hw - 10;
    std::vector<std::uint32_t> cost(static_cast<std::size_t>(count));
    ASSERT_TRUE(row_zsad(left.at(100, 20), left.width, right.at(hw + 5, 20), right.width, hw, count,
                         cost.data()));
    for (int j = 0; j < count; ++j) {
      const double want = zsad_per_px(left, 100, 20, right, hw + 5 + j, 20, hw);
      ASSERT_NEAR(cost[static_cast<std::size_t>(j)] / static_cast<double>(n * n), want, 1e-9)
          << "hw " << hw << " j " << j;
    }
  }
  // The template against itself costs nothing; against itself brighter by 40, nothing either.
  TestImage brighter = left;
  for (std::uint8_t& v : brighter.px) v = static_cast<std::uint8_t>(std::min(255, v / 2 + 40));
  TestImage halved = left;
  for (std::uint8_t& v : halved.px) v = static_cast<std::uint8_t>(v / 2);
  std::uint32_t c = 1;
  ASSERT_TRUE(
      row_zsad(halved.at(50, 20), halved.width, brighter.at(50, 20), brighter.width, 3, 1, &c));
  EXPECT_EQ(c, 0u);
}

TEST(RowZsad, RefusesWindowsAndCountsItCannotHold) {
  const TestImage im = random_image(64, 20, 3);
  std::uint32_t c = 0;
  EXPECT_FALSE(row_zsad(im.at(10, 10), im.width, im.at(10, 10), im.width, 0, 1, &c));
  EXPECT_FALSE(row_zsad(im.at(10, 10), im.width, im.at(10, 10), im.width, 8, 1, &c));
  EXPECT_FALSE(row_zsad(im.at(10, 10), im.width, im.at(10, 10), im.width, 3, 0, &c));
  EXPECT_FALSE(row_zsad(im.at(10, 10), im.width, im.at(10, 10), im.width, 3,
                        wallar::dsp::kRowZsadMaxCount + 1, &c));
}

// Every SIMD target compiled in and supported by this CPU gives the scalar reference's bits.
// WALLAR_SIMD_TARGETS=SVE: only the targets whose name contains it (the aarch64 CI stage's
// second run, on qemu's 'max' CPU).
TEST(RowZsad, EverySimdTargetOfThisMachineAgrees) {
  const TestImage left = random_image(1000, 30, 11), right = random_image(1000, 30, 12);
  const char* only = std::getenv("WALLAR_SIMD_TARGETS");
  std::size_t checked = 0;
  for (std::int64_t target : hwy::SupportedAndGeneratedTargets()) {
    if (only != nullptr && std::string(hwy::TargetName(target)).find(only) == std::string::npos)
      continue;
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE(std::string("on ") + wallar::dsp::row_zsad_target());
    EXPECT_EQ(compare_with_scalar(left, right), 5 * 14);
    ++checked;
  }
  hwy::SetSupportedTargetsForTest(0);  // back to the real CPU
  EXPECT_GE(checked, 1u) << (only != nullptr ? only : "");
}

}  // namespace
