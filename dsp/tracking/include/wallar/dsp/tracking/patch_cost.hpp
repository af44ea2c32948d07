// SPDX-License-Identifier: Apache-2.0
/// @file patch_cost.hpp
/// @brief The patch search's inner loop: an 8x8 patch against a row of windows by the
/// gain-normalised zero-mean SAD, in SIMD.
///
/// For a patch with deviations p_i from its mean and mean absolute deviation m_p, and a window
/// with deviations w_i and mean absolute deviation m_w, the cost is
///   sum_i |w_i * (m_p / m_w) - p_i| / 64,
/// or +infinity when m_w is not within m_p / 3 .. 3 m_p (no exposure change explains the
/// difference in contrast). Each SIMD lane evaluates one window with the scalar reference's
/// operations in the scalar reference's order (no fused multiply-add), so every target gives
/// the reference's bits and the search picks the same position on x86 and on ARM.
///
/// The SIMD path is chosen at run time (Highway dynamic dispatch); patch_costs_row_scalar is
/// the reference.
///
/// Threading: pure functions over caller-owned memory; call from any thread. No allocation.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wallar::dsp {

/// The patch's side (8x8 pixels).
inline constexpr int kPatchSide = 8;

/// Costs of the windows whose top-left pixels are top_left + j, j in [0, count), into cost[j].
/// `deviation` holds the patch's 64 pixels minus their mean (row-major), `patch_mad` their mean
/// absolute value (> 0). Every pixel of every window must be readable (8 rows of pitch
/// `stride`, columns 0 .. count + 6).
void patch_costs_row(const float* deviation, float patch_mad, const std::uint8_t* top_left,
                     std::ptrdiff_t stride, int count, float* cost);

/// The same in plain scalar code (the reference the SIMD paths are tested against).
void patch_costs_row_scalar(const float* deviation, float patch_mad, const std::uint8_t* top_left,
                            std::ptrdiff_t stride, int count, float* cost);

}  // namespace wallar::dsp
