// SPDX-License-Identifier: Apache-2.0
/// @file row_zsad.cpp
/// @brief Zero-mean SAD of one template along a row, with Highway's dynamic dispatch (this file
/// is compiled once per target by hwy/foreach_target.h).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "row_zsad.cpp"  // NOLINT: found through this file's folder
#include "wallar/dsp/tracking/row_zsad.hpp"

#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#ifndef WALLAR_ROW_ZSAD_COMMON
#define WALLAR_ROW_ZSAD_COMMON
#include <array>
#include <cstdlib>

namespace wallar::dsp::row_zsad_detail {

constexpr int kMaxTaps = (2 * kRowZsadMaxHalfWindow + 1) * (2 * kRowZsadMaxHalfWindow + 1);

/// What every path shares: the template's terms n T_k - sum T, each tap's offset from a patch
/// centre, and the candidates' patch sums (sliding column sums). Left uninitialised (12 KB,
/// hundreds of calls a frame): prepare() writes every entry a call reads.
struct Setup {
  int taps = 0;
  std::array<std::int32_t, kMaxTaps> term;
  std::array<std::ptrdiff_t, kMaxTaps> offset;
  alignas(64) std::array<std::int16_t, kRowZsadMaxCount> sum16;  // hw <= 3 only
  std::array<std::int32_t, kRowZsadMaxCount> sum;
};

inline bool valid(int hw, int count) {
  return hw >= 1 && hw <= kRowZsadMaxHalfWindow && count >= 1 && count <= kRowZsadMaxCount;
}

inline void prepare(const std::uint8_t* tmpl, std::ptrdiff_t tmpl_stride, const std::uint8_t* first,
                    std::ptrdiff_t stride, int hw, int count, Setup& s) {
  const int side = 2 * hw + 1;
  s.taps = side * side;
  std::int32_t sum_t = 0;
  int k = 0;
  for (int dy = -hw; dy <= hw; ++dy) {
    for (int dx = -hw; dx <= hw; ++dx, ++k) {
      const std::int32_t t = tmpl[dy * tmpl_stride + dx];
      s.term[static_cast<std::size_t>(k)] = s.taps * t;
      sum_t += t;
      s.offset[static_cast<std::size_t>(k)] = dy * stride + dx;
    }
  }
  for (int i = 0; i < s.taps; ++i) s.term[static_cast<std::size_t>(i)] -= sum_t;
  // Column sums over the window's rows, then a sliding sum along the row.
  std::array<std::int32_t, kRowZsadMaxCount + 2 * kRowZsadMaxHalfWindow> col;  // cols written
  const int cols = count + 2 * hw;
  for (int x = 0; x < cols; ++x) {
    std::int32_t c = 0;
    const std::uint8_t* p = first - hw * stride + (x - hw);
    for (int r = 0; r < side; ++r) c += p[r * stride];
    col[static_cast<std::size_t>(x)] = c;
  }
  std::int32_t run = 0;
  for (int x = 0; x < side; ++x) run += col[static_cast<std::size_t>(x)];
  for (int j = 0; j < count; ++j) {
    s.sum[static_cast<std::size_t>(j)] = run;
    s.sum16[static_cast<std::size_t>(j)] = static_cast<std::int16_t>(hw <= 3 ? run : 0);
    if (j + 1 < count) {
      run += col[static_cast<std::size_t>(j + side)] - col[static_cast<std::size_t>(j)];
    }
  }
}

inline std::uint32_t one(const Setup& s, const std::uint8_t* centre, std::int32_t sum) {
  std::uint32_t c = 0;
  for (int k = 0; k < s.taps; ++k) {
    const std::int32_t v = s.term[static_cast<std::size_t>(k)] + sum -
                           s.taps * centre[s.offset[static_cast<std::size_t>(k)]];
    c += static_cast<std::uint32_t>(std::abs(v));
  }
  return c;
}

}  // namespace wallar::dsp::row_zsad_detail
#endif  // WALLAR_ROW_ZSAD_COMMON

HWY_BEFORE_NAMESPACE();
namespace wallar::dsp {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

bool RowZsadImpl(const std::uint8_t* HWY_RESTRICT tmpl, std::ptrdiff_t tmpl_stride,
                 const std::uint8_t* HWY_RESTRICT first, std::ptrdiff_t stride, int hw, int count,
                 std::uint32_t* HWY_RESTRICT cost) {
  using row_zsad_detail::Setup;
  if (!row_zsad_detail::valid(hw, count)) return false;
  Setup s;
  row_zsad_detail::prepare(tmpl, tmpl_stride, first, stride, hw, count, s);
  int j = 0;
#if HWY_TARGET != HWY_SCALAR
  if (hw <= 3) {
    // 16-bit lanes, one candidate per lane: |n T_k - sum T + sum I - n I_k| <= 2 * 49 * 255, two
    // of them still fit unsigned 16 bits, and the pair sums widen into 32-bit accumulators.
    const hn::ScalableTag<std::int16_t> d16;
    const hn::RebindToUnsigned<decltype(d16)> du16;
    const hn::Half<decltype(du16)> du16h;
    const hn::Rebind<std::uint32_t, decltype(du16h)> du32;
    const hn::Rebind<std::uint8_t, decltype(d16)> d8;
    const int lanes = static_cast<int>(hn::Lanes(d16));
    const int half = lanes / 2;
    const auto vn = hn::Set(d16, static_cast<std::int16_t>(s.taps));
    for (; j + lanes <= count; j += lanes) {
      const auto sum = hn::LoadU(d16, s.sum16.data() + j);
      const std::uint8_t* base = first + j;
      auto lo = hn::Zero(du32), hi = hn::Zero(du32);
      const auto term = [&](int k) {
        const auto px =
            hn::PromoteTo(d16, hn::LoadU(d8, base + s.offset[static_cast<std::size_t>(k)]));
        const auto t = hn::Set(d16, static_cast<std::int16_t>(s.term[static_cast<std::size_t>(k)]));
        return hn::BitCast(du16, hn::Abs(hn::Sub(hn::Add(t, sum), hn::Mul(px, vn))));
      };
      const auto widen_add = [&](const auto v) {
        lo = hn::Add(lo, hn::PromoteTo(du32, hn::LowerHalf(du16h, v)));
        hi = hn::Add(hi, hn::PromoteTo(du32, hn::UpperHalf(du16h, v)));
      };
      int k = 0;
      for (; k + 1 < s.taps; k += 2) widen_add(hn::Add(term(k), term(k + 1)));
      if (k < s.taps) widen_add(term(k));
      hn::StoreU(lo, du32, cost + j);
      hn::StoreU(hi, du32, cost + j + half);
    }
  }
#endif
  for (; j < count; ++j) {
    cost[j] = row_zsad_detail::one(s, first + j, s.sum[static_cast<std::size_t>(j)]);
  }
  return true;
}

const char* RowZsadTargetImpl() { return hwy::TargetName(HWY_TARGET); }

}  // namespace HWY_NAMESPACE
}  // namespace wallar::dsp
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace wallar::dsp {

HWY_EXPORT(RowZsadImpl);
HWY_EXPORT(RowZsadTargetImpl);

bool row_zsad(const std::uint8_t* tmpl, std::ptrdiff_t tmpl_stride, const std::uint8_t* first,
              std::ptrdiff_t stride, int hw, int count, std::uint32_t* cost) {
  return HWY_DYNAMIC_DISPATCH(RowZsadImpl)(tmpl, tmpl_stride, first, stride, hw, count, cost);
}

const char* row_zsad_target() { return HWY_DYNAMIC_DISPATCH(RowZsadTargetImpl)(); }

bool row_zsad_scalar(const std::uint8_t* tmpl, std::ptrdiff_t tmpl_stride,
                     const std::uint8_t* first, std::ptrdiff_t stride, int hw, int count,
                     std::uint32_t* cost) {
  if (!row_zsad_detail::valid(hw, count)) return false;
  row_zsad_detail::Setup s;
  row_zsad_detail::prepare(tmpl, tmpl_stride, first, stride, hw, count, s);
  for (int j = 0; j < count; ++j) {
    cost[j] = row_zsad_detail::one(s, first + j, s.sum[static_cast<std::size_t>(j)]);
  }
  return true;
}

}  // namespace wallar::dsp
#endif  // HWY_ONCE
