// SPDX-License-Identifier: Apache-2.0
/// @file plane_kernel.hpp
/// @brief The RANSAC inner loop: one candidate plane tested against every point, in SIMD.
///
/// Points are structure-of-arrays floats, padded to a multiple of kPointPadding with NaN (NaN
/// compares false, so padding is never an inlier nor a backlier): the kernel has no tail loop.
/// For a plane n.p - d = 0 with n toward the viewer, a point with signed distance s is an
/// inlier when |s| < t (in the band's inner half when |s| < t / 2) and a backlier when s < -t
/// (behind the wall).
///
/// The SIMD path is chosen at run time (Highway dynamic dispatch: AVX-512/AVX2/SSE4 on x86-64,
/// NEON on aarch64) on top of the build's baseline; score_plane_scalar is the reference.
///
/// Threading: pure functions over caller-owned memory; call from any thread.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wallar::dsp {

/// Point arrays are padded to a multiple of this many floats (64 bytes: one cache line).
inline constexpr std::size_t kPointPadding = 16;

struct PlaneCounts {
  std::uint32_t inliers = 0;
  std::uint32_t backliers = 0;
  float inlier_sq_sum = 0.0f;  //!< sum of s^2 over the inliers [m^2] (for MSAC)
  std::uint32_t inner = 0;     //!< inliers in the band's inner half, |s| < t / 2
};

/// Tests the plane (nx, ny, nz, d) against n_padded points (n_padded % kPointPadding == 0).
PlaneCounts score_plane(const float* x, const float* y, const float* z, std::size_t n_padded,
                        float nx, float ny, float nz, float d, float threshold);

/// The same in plain scalar code (the reference the SIMD paths are tested against).
PlaneCounts score_plane_scalar(const float* x, const float* y, const float* z, std::size_t n_padded,
                               float nx, float ny, float nz, float d, float threshold);

/// Name of the SIMD target the dispatcher picked on this machine ("AVX2", "NEON", ...).
const char* plane_kernel_target();

}  // namespace wallar::dsp
