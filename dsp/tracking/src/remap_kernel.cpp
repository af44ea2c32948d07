// SPDX-License-Identifier: Apache-2.0
/// @file remap_kernel.cpp
/// @brief Fixed-point bilinear remap through a tap table, with Highway's dynamic dispatch (this
/// file is compiled once per target by hwy/foreach_target.h).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "remap_kernel.cpp"  // NOLINT: found through this file's folder
#include "wallar/dsp/tracking/remap_kernel.hpp"

#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#ifndef WALLAR_REMAP_KERNEL_COMMON
#define WALLAR_REMAP_KERNEL_COMMON
namespace wallar::dsp::remap_detail {

inline std::uint8_t one(const std::uint8_t* src, std::ptrdiff_t stride, std::uint32_t pos,
                        std::uint32_t w) {
  const std::uint8_t* p = src + static_cast<std::ptrdiff_t>(pos >> 16) * stride + (pos & 0xffff);
  const std::uint32_t sum = p[0] * (w & 0xff) + p[1] * ((w >> 8) & 0xff) +
                            p[stride] * ((w >> 16) & 0xff) + p[stride + 1] * (w >> 24);
  return static_cast<std::uint8_t>((sum + 64) >> 7);
}

}  // namespace wallar::dsp::remap_detail
#endif  // WALLAR_REMAP_KERNEL_COMMON

HWY_BEFORE_NAMESPACE();
namespace wallar::dsp {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void RemapTapsImpl(const std::uint8_t* HWY_RESTRICT src, std::ptrdiff_t stride,
                   const std::uint32_t* HWY_RESTRICT pos, const std::uint32_t* HWY_RESTRICT weights,
                   std::size_t count, std::uint8_t* HWY_RESTRICT out) {
#if HWY_TARGET == HWY_SCALAR
  for (std::size_t i = 0; i < count; ++i)
    out[i] = remap_detail::one(src, stride, pos[i], weights[i]);
#else
  const hn::ScalableTag<std::int32_t> di;
  const hn::RebindToUnsigned<decltype(di)> du;
  const hn::Rebind<std::uint8_t, decltype(di)> d8;
  const std::size_t lanes = hn::Lanes(di);
  const auto vstride = hn::Set(di, static_cast<std::int32_t>(stride));
  const auto lo16 = hn::Set(du, 0xffffu);
  const auto byte = hn::Set(du, 0xffu);
  const auto half = hn::Set(du, 64u);
  const auto* base = reinterpret_cast<const std::int32_t*>(src);
  const auto* below = reinterpret_cast<const std::int32_t*>(src + stride);
  std::size_t i = 0;
  for (; i + lanes <= count; i += lanes) {
    const auto p = hn::LoadU(du, pos + i);
    const auto w = hn::LoadU(du, weights + i);
    const auto offset = hn::Add(hn::Mul(hn::BitCast(di, hn::ShiftRight<16>(p)), vstride),
                                hn::BitCast(di, hn::And(p, lo16)));
    const auto top = hn::BitCast(du, hn::GatherOffset(di, base, offset));
    const auto bottom = hn::BitCast(du, hn::GatherOffset(di, below, offset));
    auto sum = hn::Mul(hn::And(top, byte), hn::And(w, byte));
    sum = hn::Add(
        sum, hn::Mul(hn::And(hn::ShiftRight<8>(top), byte), hn::And(hn::ShiftRight<8>(w), byte)));
    sum = hn::Add(sum, hn::Mul(hn::And(bottom, byte), hn::And(hn::ShiftRight<16>(w), byte)));
    sum = hn::Add(sum, hn::Mul(hn::And(hn::ShiftRight<8>(bottom), byte), hn::ShiftRight<24>(w)));
    const auto result = hn::ShiftRight<7>(hn::Add(sum, half));  // <= 255
    hn::StoreU(hn::DemoteTo(d8, hn::BitCast(di, result)), d8, out + i);
  }
  for (; i < count; ++i) out[i] = remap_detail::one(src, stride, pos[i], weights[i]);  // the tail
#endif
}

}  // namespace HWY_NAMESPACE
}  // namespace wallar::dsp
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace wallar::dsp {

HWY_EXPORT(RemapTapsImpl);

void remap_taps(const std::uint8_t* src, std::ptrdiff_t stride, const std::uint32_t* pos,
                const std::uint32_t* weights, std::size_t count, std::uint8_t* out) {
  HWY_DYNAMIC_DISPATCH(RemapTapsImpl)(src, stride, pos, weights, count, out);
}

void remap_taps_scalar(const std::uint8_t* src, std::ptrdiff_t stride, const std::uint32_t* pos,
                       const std::uint32_t* weights, std::size_t count, std::uint8_t* out) {
  for (std::size_t i = 0; i < count; ++i) {
    out[i] = remap_detail::one(src, stride, pos[i], weights[i]);
  }
}

}  // namespace wallar::dsp
#endif  // HWY_ONCE
