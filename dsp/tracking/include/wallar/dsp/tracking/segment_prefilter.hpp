// SPDX-License-Identifier: Apache-2.0
/// @file segment_prefilter.hpp
/// @brief The corner detector's first test, in SIMD: which pixels of a row can be segment-test
/// corners at all.
///
/// A pixel c is a candidate when at least two of its four compass pixels at radius 3 (above,
/// below, left, right) are brighter than c + t, or at least two are darker than c - t: a
/// contiguous arc of 9 of the 16 circle pixels always holds two of them, so a pixel that fails
/// cannot be a corner. The detector runs the full segment test only on candidates.
///
/// The SIMD path is chosen at run time (Highway dynamic dispatch); segment_candidates_scalar is
/// the reference (the same flags on every target).
///
/// Threading: pure functions over caller-owned memory; call from any thread. No allocation.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wallar::dsp {

/// flags[i] = 1 when centre + i is a candidate for threshold t (0..255), else 0, i in
/// [0, count). Rows -3..3 and columns -3..count+2 around `centre` must be readable.
void segment_candidates(const std::uint8_t* centre, std::ptrdiff_t stride, int count, int t,
                        std::uint8_t* flags);

/// The same in plain scalar code (the reference the SIMD paths are tested against).
void segment_candidates_scalar(const std::uint8_t* centre, std::ptrdiff_t stride, int count, int t,
                               std::uint8_t* flags);

}  // namespace wallar::dsp
