// SPDX-License-Identifier: Apache-2.0
/// @file segment_prefilter.cpp
/// @brief The segment test's compass pre-filter, with Highway's dynamic dispatch (this file is
/// compiled once per target by hwy/foreach_target.h).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "segment_prefilter.cpp"  // NOLINT: found through this file's folder
#include "wallar/dsp/tracking/segment_prefilter.hpp"

#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#ifndef WALLAR_SEGMENT_PREFILTER_COMMON
#define WALLAR_SEGMENT_PREFILTER_COMMON
namespace wallar::dsp::segment_prefilter_detail {

inline std::uint8_t one(const std::uint8_t* p, std::ptrdiff_t s, int t) {
  const int c = p[0];
  const int hi = c + t, lo = c - t;
  const int top = p[-3 * s], bottom = p[3 * s], right = p[3], left = p[-3];
  const int bright = (top > hi) + (bottom > hi) + (right > hi) + (left > hi);
  const int dark = (top < lo) + (bottom < lo) + (right < lo) + (left < lo);
  return bright >= 2 || dark >= 2 ? 1 : 0;
}

}  // namespace wallar::dsp::segment_prefilter_detail
#endif  // WALLAR_SEGMENT_PREFILTER_COMMON

HWY_BEFORE_NAMESPACE();
namespace wallar::dsp {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void SegmentCandidatesImpl(const std::uint8_t* HWY_RESTRICT centre, std::ptrdiff_t stride,
                           int count, int t, std::uint8_t* HWY_RESTRICT flags) {
  const hn::ScalableTag<std::uint8_t> d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  int i = 0;
  if (t >= 0 && t <= 255) {
    const auto vt = hn::Set(d, static_cast<std::uint8_t>(t));
    const auto one = hn::Set(d, std::uint8_t{1});
    // Saturation keeps the integer test's meaning: c + t above 255 has nothing brighter, c - t
    // below 0 nothing darker.
    for (; i + lanes <= count; i += lanes) {
      const std::uint8_t* p = centre + i;
      const auto c = hn::LoadU(d, p);
      const auto hi = hn::SaturatedAdd(c, vt), lo = hn::SaturatedSub(c, vt);
      const auto top = hn::LoadU(d, p - 3 * stride), bottom = hn::LoadU(d, p + 3 * stride);
      const auto left = hn::LoadU(d, p - 3), right = hn::LoadU(d, p + 3);
      const auto count_of = [&](auto m0, auto m1, auto m2, auto m3) {
        auto n = hn::IfThenElseZero(m0, one);
        n = hn::Add(n, hn::IfThenElseZero(m1, one));
        n = hn::Add(n, hn::IfThenElseZero(m2, one));
        return hn::Add(n, hn::IfThenElseZero(m3, one));
      };
      const auto bright =
          count_of(hn::Gt(top, hi), hn::Gt(bottom, hi), hn::Gt(left, hi), hn::Gt(right, hi));
      const auto dark =
          count_of(hn::Lt(top, lo), hn::Lt(bottom, lo), hn::Lt(left, lo), hn::Lt(right, lo));
      // Counts are 0..4: "at least two" is max(count) > 1.
      const auto m = hn::Gt(hn::Max(bright, dark), one);
      hn::StoreU(hn::IfThenElseZero(m, one), d, flags + i);
    }
  }
  for (; i < count; ++i) flags[i] = segment_prefilter_detail::one(centre + i, stride, t);
}

}  // namespace HWY_NAMESPACE
}  // namespace wallar::dsp
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace wallar::dsp {

HWY_EXPORT(SegmentCandidatesImpl);

void segment_candidates(const std::uint8_t* centre, std::ptrdiff_t stride, int count, int t,
                        std::uint8_t* flags) {
  HWY_DYNAMIC_DISPATCH(SegmentCandidatesImpl)(centre, stride, count, t, flags);
}

void segment_candidates_scalar(const std::uint8_t* centre, std::ptrdiff_t stride, int count, int t,
                               std::uint8_t* flags) {
  for (int i = 0; i < count; ++i) flags[i] = segment_prefilter_detail::one(centre + i, stride, t);
}

}  // namespace wallar::dsp
#endif  // HWY_ONCE
