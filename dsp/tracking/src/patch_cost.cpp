// SPDX-License-Identifier: Apache-2.0
/// @file patch_cost.cpp
/// @brief The gain-normalised zero-mean SAD of an 8x8 patch along a row of windows, with
/// Highway's dynamic dispatch (this file is compiled once per target by hwy/foreach_target.h).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "patch_cost.cpp"  // NOLINT: found through this file's folder
#include "wallar/dsp/tracking/patch_cost.hpp"

#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#ifndef WALLAR_PATCH_COST_COMMON
#define WALLAR_PATCH_COST_COMMON
#include <cmath>
#include <limits>

namespace wallar::dsp::patch_cost_detail {

/// One window, the reference's operations in its order.
inline float one(const float* deviation, float patch_mad, const std::uint8_t* top_left,
                 std::ptrdiff_t stride) {
  int sum = 0;
  for (int r = 0; r < kPatchSide; ++r) {
    for (int c = 0; c < kPatchSide; ++c) sum += top_left[r * stride + c];
  }
  const float mean = static_cast<float>(sum) / 64.0f;
  float mad = 0.0f;
  for (int r = 0; r < kPatchSide; ++r) {
    for (int c = 0; c < kPatchSide; ++c) {
      mad += std::abs(static_cast<float>(top_left[r * stride + c]) - mean);
    }
  }
  mad /= 64.0f;
  // Gains within 1/3..3 of the patch's contrast are an exposure change; beyond, not a match.
  if (!(mad > patch_mad * (1.0f / 3.0f) && mad < patch_mad * 3.0f)) {
    return std::numeric_limits<float>::infinity();
  }
  const float gain = patch_mad / mad;
  float cost = 0.0f;
  for (int r = 0; r < kPatchSide; ++r) {
    for (int c = 0; c < kPatchSide; ++c) {
      const float w = static_cast<float>(top_left[r * stride + c]) - mean;
      cost += std::abs(w * gain - deviation[r * kPatchSide + c]);
    }
  }
  return cost / 64.0f;
}

}  // namespace wallar::dsp::patch_cost_detail
#endif  // WALLAR_PATCH_COST_COMMON

HWY_BEFORE_NAMESPACE();
namespace wallar::dsp {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void PatchCostsRowImpl(const float* HWY_RESTRICT deviation, float patch_mad,
                       const std::uint8_t* HWY_RESTRICT top_left, std::ptrdiff_t stride, int count,
                       float* HWY_RESTRICT cost) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const hn::Rebind<std::uint8_t, decltype(df)> d8;
  const int lanes = static_cast<int>(hn::Lanes(df));
  if (lanes == 1 || count < lanes) {
    for (int j = 0; j < count; ++j) {
      cost[j] = patch_cost_detail::one(deviation, patch_mad, top_left + j, stride);
    }
    return;
  }
  const auto n = hn::Set(df, 64.0f);
  const auto lo = hn::Set(df, patch_mad * (1.0f / 3.0f));
  const auto hi = hn::Set(df, patch_mad * 3.0f);
  const auto mad_p = hn::Set(df, patch_mad);
  const auto inf = hn::Set(df, std::numeric_limits<float>::infinity());
  // One window per lane; the last block overlaps the one before (same values written twice)
  // instead of a scalar tail.
  for (int j = 0; j < count; j += lanes) {
    const int at = j + lanes <= count ? j : count - lanes;
    const std::uint8_t* base = top_left + at;
    const auto pixel = [&](int r, int c) {
      return hn::PromoteTo(di, hn::LoadU(d8, base + r * stride + c));
    };
    auto sum = hn::Zero(di);
    for (int r = 0; r < kPatchSide; ++r) {
      for (int c = 0; c < kPatchSide; ++c) sum = hn::Add(sum, pixel(r, c));
    }
    const auto mean = hn::Div(hn::ConvertTo(df, sum), n);
    auto mad = hn::Zero(df);
    for (int r = 0; r < kPatchSide; ++r) {
      for (int c = 0; c < kPatchSide; ++c) {
        mad = hn::Add(mad, hn::Abs(hn::Sub(hn::ConvertTo(df, pixel(r, c)), mean)));
      }
    }
    mad = hn::Div(mad, n);
    const auto ok = hn::And(hn::Gt(mad, lo), hn::Lt(mad, hi));
    const auto gain = hn::Div(mad_p, mad);
    auto c_sum = hn::Zero(df);
    for (int r = 0; r < kPatchSide; ++r) {
      for (int c = 0; c < kPatchSide; ++c) {
        const auto w = hn::Sub(hn::ConvertTo(df, pixel(r, c)), mean);
        const auto p = hn::Set(df, deviation[r * kPatchSide + c]);
        c_sum = hn::Add(c_sum, hn::Abs(hn::Sub(hn::Mul(w, gain), p)));
      }
    }
    hn::StoreU(hn::IfThenElse(ok, hn::Div(c_sum, n), inf), df, cost + at);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace wallar::dsp
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace wallar::dsp {

HWY_EXPORT(PatchCostsRowImpl);

void patch_costs_row(const float* deviation, float patch_mad, const std::uint8_t* top_left,
                     std::ptrdiff_t stride, int count, float* cost) {
  HWY_DYNAMIC_DISPATCH(PatchCostsRowImpl)(deviation, patch_mad, top_left, stride, count, cost);
}

void patch_costs_row_scalar(const float* deviation, float patch_mad, const std::uint8_t* top_left,
                            std::ptrdiff_t stride, int count, float* cost) {
  for (int j = 0; j < count; ++j) {
    cost[j] = patch_cost_detail::one(deviation, patch_mad, top_left + j, stride);
  }
}

}  // namespace wallar::dsp
#endif  // HWY_ONCE
