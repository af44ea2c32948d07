// SPDX-License-Identifier: Apache-2.0
/// @file plane_kernel.cpp
/// @brief SIMD plane scoring with Highway's dynamic dispatch (this file is compiled once per
/// target by hwy/foreach_target.h).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "plane_kernel.cpp"  // NOLINT: found through this file's folder
#include "wallar/dsp/walls/plane_kernel.hpp"

#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace wallar::dsp {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

PlaneCounts ScorePlaneImpl(const float* HWY_RESTRICT x, const float* HWY_RESTRICT y,
                           const float* HWY_RESTRICT z, std::size_t n_padded, float nx, float ny,
                           float nz, float d, float threshold) {
  const hn::ScalableTag<float> df;
  const std::size_t lanes = hn::Lanes(df);
  const auto vnx = hn::Set(df, nx);
  const auto vny = hn::Set(df, ny);
  const auto vnz = hn::Set(df, nz);
  const auto vmd = hn::Set(df, -d);
  const auto vt = hn::Set(df, threshold);
  const auto vmt = hn::Set(df, -threshold);
  const auto vht = hn::Set(df, 0.5f * threshold);
  const auto one = hn::Set(df, 1.0f);
  // Two independent accumulator sets hide the add latency.
  auto in0 = hn::Zero(df), in1 = hn::Zero(df);
  auto bk0 = hn::Zero(df), bk1 = hn::Zero(df);
  auto sq0 = hn::Zero(df), sq1 = hn::Zero(df);
  auto ir0 = hn::Zero(df), ir1 = hn::Zero(df);
  std::size_t i = 0;
  for (; i + 2 * lanes <= n_padded; i += 2 * lanes) {
    const auto s0 = hn::MulAdd(
        vnx, hn::LoadU(df, x + i),
        hn::MulAdd(vny, hn::LoadU(df, y + i), hn::MulAdd(vnz, hn::LoadU(df, z + i), vmd)));
    const auto s1 = hn::MulAdd(vnx, hn::LoadU(df, x + i + lanes),
                               hn::MulAdd(vny, hn::LoadU(df, y + i + lanes),
                                          hn::MulAdd(vnz, hn::LoadU(df, z + i + lanes), vmd)));
    const auto a0 = hn::Abs(s0);
    const auto a1 = hn::Abs(s1);
    const auto m0 = hn::Lt(a0, vt);
    const auto m1 = hn::Lt(a1, vt);
    in0 = hn::Add(in0, hn::IfThenElseZero(m0, one));
    in1 = hn::Add(in1, hn::IfThenElseZero(m1, one));
    ir0 = hn::Add(ir0, hn::IfThenElseZero(hn::Lt(a0, vht), one));
    ir1 = hn::Add(ir1, hn::IfThenElseZero(hn::Lt(a1, vht), one));
    bk0 = hn::Add(bk0, hn::IfThenElseZero(hn::Lt(s0, vmt), one));
    bk1 = hn::Add(bk1, hn::IfThenElseZero(hn::Lt(s1, vmt), one));
    sq0 = hn::Add(sq0, hn::IfThenElseZero(m0, hn::Mul(s0, s0)));
    sq1 = hn::Add(sq1, hn::IfThenElseZero(m1, hn::Mul(s1, s1)));
  }
  for (; i < n_padded; i += lanes) {  // an odd number of vectors (narrow targets)
    const auto s0 = hn::MulAdd(
        vnx, hn::LoadU(df, x + i),
        hn::MulAdd(vny, hn::LoadU(df, y + i), hn::MulAdd(vnz, hn::LoadU(df, z + i), vmd)));
    const auto a0 = hn::Abs(s0);
    const auto m0 = hn::Lt(a0, vt);
    in0 = hn::Add(in0, hn::IfThenElseZero(m0, one));
    ir0 = hn::Add(ir0, hn::IfThenElseZero(hn::Lt(a0, vht), one));
    bk0 = hn::Add(bk0, hn::IfThenElseZero(hn::Lt(s0, vmt), one));
    sq0 = hn::Add(sq0, hn::IfThenElseZero(m0, hn::Mul(s0, s0)));
  }
  PlaneCounts c;
  c.inliers = static_cast<std::uint32_t>(hn::GetLane(hn::SumOfLanes(df, hn::Add(in0, in1))));
  c.backliers = static_cast<std::uint32_t>(hn::GetLane(hn::SumOfLanes(df, hn::Add(bk0, bk1))));
  c.inlier_sq_sum = hn::GetLane(hn::SumOfLanes(df, hn::Add(sq0, sq1)));
  c.inner = static_cast<std::uint32_t>(hn::GetLane(hn::SumOfLanes(df, hn::Add(ir0, ir1))));
  return c;
}

const char* TargetNameImpl() { return hwy::TargetName(HWY_TARGET); }

}  // namespace HWY_NAMESPACE
}  // namespace wallar::dsp
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace wallar::dsp {

HWY_EXPORT(ScorePlaneImpl);
HWY_EXPORT(TargetNameImpl);

PlaneCounts score_plane(const float* x, const float* y, const float* z, std::size_t n_padded,
                        float nx, float ny, float nz, float d, float threshold) {
  return HWY_DYNAMIC_DISPATCH(ScorePlaneImpl)(x, y, z, n_padded, nx, ny, nz, d, threshold);
}

const char* plane_kernel_target() { return HWY_DYNAMIC_DISPATCH(TargetNameImpl)(); }

PlaneCounts score_plane_scalar(const float* x, const float* y, const float* z, std::size_t n_padded,
                               float nx, float ny, float nz, float d, float threshold) {
  PlaneCounts c;
  for (std::size_t i = 0; i < n_padded; ++i) {
    const float s = nx * x[i] + ny * y[i] + nz * z[i] - d;
    if (s < threshold && s > -threshold) {
      ++c.inliers;
      c.inlier_sq_sum += s * s;
    }
    if (s < 0.5f * threshold && s > -0.5f * threshold) ++c.inner;
    if (s < -threshold) ++c.backliers;
  }
  return c;
}

}  // namespace wallar::dsp
#endif  // HWY_ONCE
