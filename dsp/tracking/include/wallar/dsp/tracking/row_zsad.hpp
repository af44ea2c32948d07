// SPDX-License-Identifier: Apache-2.0
/// @file row_zsad.hpp
/// @brief The stereo row search's inner loop: one template patch against many consecutive
/// positions of a row, by zero-mean SAD, in SIMD.
///
/// For a template T and a candidate patch I of n = (2hw+1)^2 pixels, the zero-mean SAD per
/// pixel is sum_k |(T_k - mean T) - (I_k - mean I)| / n. Multiplied by n^2 it is the integer
///   sum_k |n T_k - sum T - n I_k + sum I|,
/// which is what these functions return: exact, so every SIMD target and the scalar reference
/// give the same bits and the search picks the same match on x86 and on the board's ARM core.
/// For hw <= 3 every term fits 16-bit lanes (|term| <= 2 * 49 * 255); larger windows take the
/// scalar path.
///
/// The SIMD path is chosen at run time (Highway dynamic dispatch: AVX-512/AVX2/SSE4 on x86-64,
/// NEON/SVE on aarch64); row_zsad_scalar is the reference.
///
/// Threading: pure functions over caller-owned memory; call from any thread. No allocation.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wallar::dsp {

/// The most positions one call scores.
inline constexpr int kRowZsadMaxCount = 1024;
/// The largest half window (7x7 .. 15x15 patches; above 3 the scalar path).
inline constexpr int kRowZsadMaxHalfWindow = 7;

/// Scores the template centred at `tmpl` (row pitch `tmpl_stride`) against the patches centred
/// at first + j for j in [0, count), all of half window `hw`, into cost[j] (n^2 times the
/// zero-mean SAD per pixel). The caller guarantees every pixel of every patch is readable
/// (rows -hw..hw, columns -hw..count-1+hw around `first`). hw in [1, kRowZsadMaxHalfWindow],
/// count in [1, kRowZsadMaxCount]; outside, nothing is written and false is returned.
bool row_zsad(const std::uint8_t* tmpl, std::ptrdiff_t tmpl_stride, const std::uint8_t* first,
              std::ptrdiff_t stride, int hw, int count, std::uint32_t* cost);

/// The same in plain scalar code (the reference the SIMD paths are tested against).
bool row_zsad_scalar(const std::uint8_t* tmpl, std::ptrdiff_t tmpl_stride,
                     const std::uint8_t* first, std::ptrdiff_t stride, int hw, int count,
                     std::uint32_t* cost);

/// Name of the SIMD target the dispatcher picked on this machine ("AVX2", "NEON", ...).
const char* row_zsad_target();

}  // namespace wallar::dsp
