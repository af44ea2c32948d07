// SPDX-License-Identifier: Apache-2.0
/// @file remap_kernel.hpp
/// @brief The rectification's inner loop: a fixed-point bilinear remap through a precomputed
/// tap table, in SIMD (gathers).
///
/// Tap i: pos[i] = (y << 16) | x, the top-left source pixel of the 2x2 neighbourhood, and
/// weights[i] = w00 | w01 << 8 | w10 << 16 | w11 << 24 in 1/128 (top-left, top-right,
/// bottom-left, bottom-right); out[i] = (sum of pixel x weight + 64) >> 7. A tap outside the
/// source is pos 0 with zero weights (black). The result is integer-exact: every target gives
/// the scalar reference's bytes.
///
/// The SIMD path reads four bytes from each of the two source rows of a tap: the caller keeps
/// it to taps whose x + 3 is inside the buffer on the lower row (RemapTable sends the others,
/// the source's bottom-right corner, to the scalar path).
///
/// Threading: pure functions over caller-owned memory; call from any thread. No allocation.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wallar::dsp {

/// Remaps `count` taps from `src` (row pitch `stride`) into out: whole vectors in SIMD, the
/// last count % lanes taps in scalar code (the same bytes).
void remap_taps(const std::uint8_t* src, std::ptrdiff_t stride, const std::uint32_t* pos,
                const std::uint32_t* weights, std::size_t count, std::uint8_t* out);

/// The same in plain scalar code, any count (the reference, and the table's unsafe chunks).
void remap_taps_scalar(const std::uint8_t* src, std::ptrdiff_t stride, const std::uint32_t* pos,
                       const std::uint32_t* weights, std::size_t count, std::uint8_t* out);

/// Taps per chunk of RemapTable's safety flags: a multiple of every target's lane count (up to
/// 2048-bit SVE).
inline constexpr std::size_t kRemapChunk = 64;

}  // namespace wallar::dsp
