// SPDX-License-Identifier: Apache-2.0
// The tracker's image kernels (the rectification's remap, the corner detector's pre-filter, the
// stereo row search's zero-mean SAD, the patch search's gain-normalised SAD): exact agreement of
// every SIMD target with the scalar reference, and each cost against its definition computed in
// double precision.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "simd_targets.hpp"
#include "wallar/core/hash.hpp"
#include "wallar/dsp/tracking/gray_image.hpp"
#include "wallar/dsp/tracking/patch_cost.hpp"
#include "wallar/dsp/tracking/row_zsad.hpp"
#include "wallar/dsp/tracking/segment_prefilter.hpp"

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
TEST(RowZsad, EverySimdTargetOfThisMachineAgrees) {
  const TestImage left = random_image(1000, 30, 11), right = random_image(1000, 30, 12);
  const std::size_t ran = wallar::test::for_each_simd_target([&] {
    SCOPED_TRACE(std::string("dispatched to ") + wallar::dsp::row_zsad_target());
    EXPECT_EQ(compare_with_scalar(left, right), 5 * 14);
  });
  EXPECT_GE(ran, 1u) << wallar::test::simd_filter();
}

/// An 8x8 patch's deviations from its mean and their mean absolute value, as search_patch
/// makes them.
struct PatchDev {
  std::array<float, 64> dev{};
  float mad = 0.0f;
};
PatchDev patch_at(const TestImage& im, int x, int y) {
  PatchDev p;
  float mean = 0.0f;
  for (int r = 0; r < 8; ++r) {
    for (int c = 0; c < 8; ++c) mean += *im.at(x + c, y + r);
  }
  mean /= 64.0f;
  for (int r = 0; r < 8; ++r) {
    for (int c = 0; c < 8; ++c) {
      p.dev[static_cast<std::size_t>(8 * r + c)] = static_cast<float>(*im.at(x + c, y + r)) - mean;
      p.mad += std::abs(p.dev[static_cast<std::size_t>(8 * r + c)]);
    }
  }
  p.mad /= 64.0f;
  return p;
}

/// The definition in double precision: +inf outside the contrast range.
double patch_cost_definition(const PatchDev& p, const TestImage& im, int x, int y) {
  double mean = 0.0;
  for (int r = 0; r < 8; ++r) {
    for (int c = 0; c < 8; ++c) mean += *im.at(x + c, y + r);
  }
  mean /= 64.0;
  double mad = 0.0;
  for (int r = 0; r < 8; ++r) {
    for (int c = 0; c < 8; ++c) mad += std::abs(*im.at(x + c, y + r) - mean);
  }
  mad /= 64.0;
  if (!(mad > p.mad / 3.0 && mad < p.mad * 3.0)) return std::numeric_limits<double>::infinity();
  double cost = 0.0;
  for (int r = 0; r < 8; ++r) {
    for (int c = 0; c < 8; ++c) {
      cost += std::abs((*im.at(x + c, y + r) - mean) * (p.mad / mad) -
                       p.dev[static_cast<std::size_t>(8 * r + c)]);
    }
  }
  return cost / 64.0;
}

/// A textured image with flat (contrast-free) and low-contrast stretches, so that the contrast
/// test rejects some windows and passes others.
TestImage patchy_image(int width, int height, std::uint32_t seed) {
  TestImage im = random_image(width, height, seed);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      std::uint8_t& v = im.px[static_cast<std::size_t>(y * width + x)];
      if ((x / 24) % 4 == 1) v = 90;                                       // flat
      if ((x / 24) % 4 == 2) v = static_cast<std::uint8_t>(100 + v / 12);  // low contrast
    }
  }
  return im;
}

int compare_patch_costs(const TestImage& patch_image, const TestImage& im) {
  int cases = 0;
  std::mt19937 rng(5);
  for (int count : {1, 2, 3, 7, 8, 9, 15, 16, 17, 31, 33, 64, 97}) {
    const PatchDev p = patch_at(patch_image, 3 + static_cast<int>(rng() % 100), 3);
    if (!(p.mad > 0.5f)) continue;
    const int x0 = static_cast<int>(rng() % static_cast<std::uint32_t>(im.width - count - 8));
    const int y0 = static_cast<int>(rng() % static_cast<std::uint32_t>(im.height - 8));
    std::vector<float> simd(static_cast<std::size_t>(count) + 1, -1.0f);
    std::vector<float> ref(static_cast<std::size_t>(count), -2.0f);
    wallar::dsp::patch_costs_row(p.dev.data(), p.mad, im.at(x0, y0), im.width, count, simd.data());
    wallar::dsp::patch_costs_row_scalar(p.dev.data(), p.mad, im.at(x0, y0), im.width, count,
                                        ref.data());
    for (int j = 0; j < count; ++j) {
      EXPECT_EQ(std::memcmp(&simd[static_cast<std::size_t>(j)], &ref[static_cast<std::size_t>(j)],
                            sizeof(float)),
                0)
          << "count " << count << " j " << j << ": " << simd[static_cast<std::size_t>(j)] << " vs "
          << ref[static_cast<std::size_t>(j)];
    }
    EXPECT_EQ(simd[static_cast<std::size_t>(count)], -1.0f) << "wrote past the end";
    ++cases;
  }
  return cases;
}

TEST(PatchCost, TheCostIsTheGainNormalisedZeroMeanSad) {
  const TestImage a = patchy_image(240, 24, 21), b = patchy_image(240, 24, 22);
  const PatchDev p = patch_at(a, 5, 4);
  ASSERT_GT(p.mad, 0.5f);
  const int count = 240 - 8;
  std::vector<float> cost(static_cast<std::size_t>(count));
  wallar::dsp::patch_costs_row(p.dev.data(), p.mad, b.at(0, 8), b.width, count, cost.data());
  int rejected = 0, scored = 0;
  for (int j = 0; j < count; ++j) {
    const double want = patch_cost_definition(p, b, j, 8);
    if (std::isinf(want)) {
      EXPECT_TRUE(std::isinf(cost[static_cast<std::size_t>(j)])) << j;
      ++rejected;
    } else {
      EXPECT_NEAR(cost[static_cast<std::size_t>(j)], want, 1e-3) << j;
      ++scored;
    }
  }
  EXPECT_GT(rejected, 40);  // the flat and the low-contrast stretches
  EXPECT_GT(scored, 40);
  // A window that is the patch at twice the contrast and another brightness (an exposure
  // change: doubled = 2 (changed - 60) exactly) costs nothing.
  TestImage changed = a;
  for (std::uint8_t& v : changed.px) v = static_cast<std::uint8_t>(60 + v / 2);
  float c = -1.0f;
  const PatchDev even = patch_at(changed, 4, 4);
  TestImage doubled = changed;
  for (std::uint8_t& v : doubled.px) v = static_cast<std::uint8_t>((v - 60) * 2);
  wallar::dsp::patch_costs_row(even.dev.data(), even.mad, doubled.at(4, 4), doubled.width, 1, &c);
  EXPECT_NEAR(c, 0.0f, 1e-4f);
}

TEST(PatchCost, EverySimdTargetOfThisMachineAgrees) {
  const TestImage a = patchy_image(300, 24, 31), b = patchy_image(300, 24, 32);
  const std::size_t ran =
      wallar::test::for_each_simd_target([&] { EXPECT_GE(compare_patch_costs(a, b), 10); });
  EXPECT_GE(ran, 1u) << wallar::test::simd_filter();
}

/// A lens-like map: the destination sampled from a rotated, scaled, radially distorted source,
/// reaching past every border (black taps) and into the bottom-right corner.
wallar::dsp::RemapTable distorted_table(int w, int h, int sw, int sh) {
  std::vector<float> mx(static_cast<std::size_t>(w * h)), my(mx.size());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double u = (x - 0.5 * w) / w, v = (y - 0.5 * h) / w;
      const double r2 = u * u + v * v, k = 1.0 + 0.3 * r2;
      const double c = std::cos(0.05), s = std::sin(0.05);
      mx[static_cast<std::size_t>(y * w + x)] =
          static_cast<float>(0.5 * sw + 1.08 * sw * k * (c * u - s * v) + 0.37);
      my[static_cast<std::size_t>(y * w + x)] =
          static_cast<float>(0.5 * sh + 1.08 * sw * k * (s * u + c * v) - 0.21);
    }
  }
  return wallar::dsp::RemapTable(w, h, mx, my, sw, sh);
}

/// Random spans (rectifying on demand: starting and ending anywhere, inside a kernel chunk,
/// across rows, on the last pixels) against the whole image `whole`: the pixels they cover
/// must hold its bytes, the others be untouched. Returns the pixels that differ.
int spans_agree(const wallar::dsp::RemapTable& table, const wallar::dsp::GrayView& view,
                const std::vector<std::uint8_t>& whole) {
  const std::size_t n = static_cast<std::size_t>(table.width() * table.height());
  std::vector<std::uint8_t> out(whole.size(), 0xee);
  std::vector<bool> covered(n, false);
  std::uint64_t state = 7;
  for (std::size_t at = 0; at < n;) {
    const std::size_t len =
        std::min<std::size_t>(1 + wallar::core::splitmix64_next(state) % 97, n - at);
    if (wallar::core::splitmix64_next(state) % 4 != 0) {
      table.apply_span(view, out.data(), at, len);
      for (std::size_t i = at; i < at + len; ++i) covered[i] = true;
    }
    at += len;
  }
  int differ = 0;
  for (std::size_t i = 0; i < n; ++i) differ += out[i] != (covered[i] ? whole[i] : 0xee) ? 1 : 0;
  for (std::size_t i = n; i < out.size(); ++i) differ += out[i] != 0xee ? 1 : 0;
  return differ;
}

int compare_remaps(const TestImage& src, int stride_pad) {
  TestImage padded{src.width + stride_pad, src.height,
                   std::vector<std::uint8_t>(
                       static_cast<std::size_t>((src.width + stride_pad) * src.height), 0x5a)};
  for (int y = 0; y < src.height; ++y) {
    std::memcpy(padded.px.data() + static_cast<std::ptrdiff_t>(y) * padded.width, src.at(0, y),
                static_cast<std::size_t>(src.width));
  }
  const wallar::dsp::GrayView view{padded.px.data(), src.width, src.height, padded.width};
  int cases = 0;
  for (const auto& [w, h] : {std::pair{src.width, src.height}, std::pair{101, 37}}) {
    const wallar::dsp::RemapTable table = distorted_table(w, h, src.width, src.height);
    EXPECT_FALSE(table.identity());
    std::vector<std::uint8_t> simd(static_cast<std::size_t>(w * h) + 1, 0xee), ref(simd);
    table.apply(view, simd.data());
    table.apply_scalar(view, ref.data());
    EXPECT_EQ(simd, ref) << w << "x" << h << ", row pitch +" << stride_pad;
    // Spans (rectifying on demand) give the same bytes as the whole image, touch nothing else,
    // and may start and end anywhere: inside a kernel chunk, across rows, on the last pixels.
    EXPECT_EQ(spans_agree(table, view, simd), 0) << w << "x" << h << ", row pitch +" << stride_pad;
    std::vector<std::uint8_t> spans(simd.size(), 0xee);
    EXPECT_THROW(table.apply_span(view, spans.data(), static_cast<std::size_t>(w * h) - 3, 4),
                 std::invalid_argument);
    int black = 0;
    for (int i = 0; i < w * h; ++i) black += simd[static_cast<std::size_t>(i)] == 0 ? 1 : 0;
    EXPECT_GT(black, w) << "the map reaches past the borders";
    ++cases;
  }
  return cases;
}

TEST(RemapKernel, EverySimdTargetOfThisMachineAgrees) {
  const TestImage src = random_image(320, 96, 41);
  const std::size_t ran = wallar::test::for_each_simd_target([&] {
    EXPECT_EQ(compare_remaps(src, 0), 2);   // packed rows: the last bytes are the buffer's end
    EXPECT_EQ(compare_remaps(src, 13), 2);  // a row pitch wider than the image
  });
  EXPECT_GE(ran, 1u) << wallar::test::simd_filter();
}

TEST(RemapKernel, AnIdentityTableCopiesWhatTheTapsWouldGive) {
  const int w = 200, h = 50;
  const TestImage src = random_image(w, h, 43);
  std::vector<float> mx(static_cast<std::size_t>(w * h)), my(mx.size());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // What initUndistortRectifyMap gives for a rectified rig: whole pixels, within rounding.
      mx[static_cast<std::size_t>(y * w + x)] =
          static_cast<float>(x) - ((x + y) % 3 == 0 ? 1e-5f : 0.0f);
      my[static_cast<std::size_t>(y * w + x)] =
          static_cast<float>(y) + ((x * y) % 5 == 0 ? 1e-5f : 0.0f);
    }
  }
  const wallar::dsp::RemapTable table(w, h, mx, my, w, h);
  EXPECT_TRUE(table.identity());
  const wallar::dsp::GrayView view{src.px.data(), w, h, w};
  std::vector<std::uint8_t> fast(static_cast<std::size_t>(w * h)), ref(fast.size());
  table.apply(view, fast.data());
  table.apply_scalar(view, ref.data());
  EXPECT_EQ(fast, ref);
  EXPECT_EQ(fast[static_cast<std::size_t>(10 * w + 17)], *src.at(17, 10));
  EXPECT_EQ(spans_agree(table, view, fast), 0);  // rows copied, the border's pixels black
  // Half a pixel off is not the identity.
  for (float& x : mx) x += 0.5f;
  EXPECT_FALSE(wallar::dsp::RemapTable(w, h, mx, my, w, h).identity());
}

/// True when the radius-3 circle around (x, y) has 9 contiguous pixels all brighter than c + t
/// or all darker than c - t (the segment test's corner condition), from its definition.
bool has_segment(const TestImage& im, int x, int y, int t) {
  static constexpr int kRing[16][2] = {{0, -3}, {1, -3},  {2, -2},  {3, -1}, {3, 0},  {3, 1},
                                       {2, 2},  {1, 3},   {0, 3},   {-1, 3}, {-2, 2}, {-3, 1},
                                       {-3, 0}, {-3, -1}, {-2, -2}, {-1, -3}};
  const int c = *im.at(x, y);
  for (int sign : {1, -1}) {
    for (int start = 0; start < 16; ++start) {
      bool all = true;
      for (int k = 0; k < 9 && all; ++k) {
        const int* o = kRing[(start + k) % 16];
        const int v = *im.at(x + o[0], y + o[1]);
        all = sign > 0 ? v > c + t : v < c - t;
      }
      if (all) return true;
    }
  }
  return false;
}

/// Bright and dark blobs on a mid-grey ground with noise: corners of both kinds, flat stretches,
/// and pixels near 0 and 255 where c + t and c - t leave the byte range.
TestImage blob_image(int width, int height, std::uint32_t seed) {
  std::mt19937 rng(seed);
  TestImage im{width, height, std::vector<std::uint8_t>(static_cast<std::size_t>(width * height))};
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      int v = 128 + static_cast<int>(rng() % 9) - 4;
      if ((x / 5 + y / 4) % 7 == 0) v = 250 + static_cast<int>(rng() % 6);
      if ((x / 6 + 2 * (y / 5)) % 9 == 0) v = static_cast<int>(rng() % 6);
      im.px[static_cast<std::size_t>(y * width + x)] = static_cast<std::uint8_t>(v);
    }
  }
  return im;
}

int compare_prefilter(const TestImage& im) {
  int cases = 0;
  for (int t : {0, 1, 7, 20, 60, 127, 200, 255}) {
    for (int y = 3; y < im.height - 3; ++y) {
      const int count = im.width - 6;
      std::vector<std::uint8_t> simd(static_cast<std::size_t>(count) + 1, 0x77), ref(simd);
      wallar::dsp::segment_candidates(im.at(3, y), im.width, count, t, simd.data());
      wallar::dsp::segment_candidates_scalar(im.at(3, y), im.width, count, t, ref.data());
      EXPECT_EQ(simd, ref) << "t " << t << " row " << y;
    }
    ++cases;
  }
  return cases;
}

TEST(SegmentPrefilter, NoPixelItRejectsIsACorner) {
  const TestImage im = blob_image(203, 61, 51);
  int candidates = 0, corners = 0, checked = 0;
  for (int t : {5, 20, 60}) {
    for (int y = 3; y < im.height - 3; ++y) {
      const int count = im.width - 6;
      std::vector<std::uint8_t> flags(static_cast<std::size_t>(count));
      wallar::dsp::segment_candidates(im.at(3, y), im.width, count, t, flags.data());
      for (int i = 0; i < count; ++i) {
        const bool corner = has_segment(im, 3 + i, y, t);
        if (corner) {
          EXPECT_EQ(flags[static_cast<std::size_t>(i)], 1) << 3 + i << "," << y;
        }
        corners += corner ? 1 : 0;
        candidates += flags[static_cast<std::size_t>(i)];
        ++checked;
      }
    }
  }
  EXPECT_GT(corners, 100);
  EXPECT_LT(candidates, checked / 2) << "the pre-filter must reject most of the image";
}

TEST(SegmentPrefilter, EverySimdTargetOfThisMachineAgrees) {
  const TestImage a = blob_image(150, 30, 52), b = random_image(150, 30, 53);
  const std::size_t ran = wallar::test::for_each_simd_target([&] {
    EXPECT_EQ(compare_prefilter(a), 8);
    EXPECT_EQ(compare_prefilter(b), 8);
  });
  EXPECT_GE(ran, 1u) << wallar::test::simd_filter();
}

}  // namespace
