// SPDX-License-Identifier: Apache-2.0
/// @file gray_image.hpp
/// @brief 8-bit gray images for the tracker: owned buffers allocated once, views, pyramids,
/// bilinear sampling, and a precomputed rectification table applied without allocation.
///
/// Threading: none; one owner. Views do not own their pixels.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace wallar::dsp {

/// A non-owning view of 8-bit gray pixels.
struct GrayView {
  const std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  int stride = 0;  //!< bytes per row

  [[nodiscard]] const std::uint8_t* row(int y) const { return data + std::ptrdiff_t{y} * stride; }
  [[nodiscard]] std::uint8_t at(int x, int y) const { return row(y)[x]; }
  [[nodiscard]] bool empty() const { return data == nullptr; }
  /// Bilinear sample at (x, y); the caller keeps (x, y) within [0, w-1) x [0, h-1).
  [[nodiscard]] float sample(float x, float y) const {
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const float ax = x - static_cast<float>(x0), ay = y - static_cast<float>(y0);
    const std::uint8_t* r0 = row(y0) + x0;
    const std::uint8_t* r1 = r0 + stride;
    return (1.0f - ay) * ((1.0f - ax) * r0[0] + ax * r0[1]) +
           ay * ((1.0f - ax) * r1[0] + ax * r1[1]);
  }
  /// Bilinear samples at (x + i, y + j), i in [0, cols), j in [0, rows), row-major into `out`.
  /// Every sample of a whole-pixel grid shares one pair of fractional weights, found once. The
  /// caller keeps the grid and its right and lower neighbours inside (x, y >= 0).
  void sample_grid(float x, float y, int cols, int rows, float* out) const {
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const float ax = x - static_cast<float>(x0), ay = y - static_cast<float>(y0);
    const float bx = 1.0f - ax, by = 1.0f - ay;
    for (int j = 0; j < rows; ++j) {
      const std::uint8_t* r0 = row(y0 + j) + x0;
      const std::uint8_t* r1 = r0 + stride;
      float* o = out + static_cast<std::ptrdiff_t>(j) * cols;
      for (int i = 0; i < cols; ++i) {
        o[i] = by * (bx * static_cast<float>(r0[i]) + ax * static_cast<float>(r0[i + 1])) +
               ay * (bx * static_cast<float>(r1[i]) + ax * static_cast<float>(r1[i + 1]));
      }
    }
  }
  [[nodiscard]] bool inside(float x, float y, float border) const {
    return x >= border && y >= border && x < static_cast<float>(width) - 1.0f - border &&
           y < static_cast<float>(height) - 1.0f - border;
  }
};

/// An owned gray image whose buffer is allocated once (construction or first allocate()).
class GrayImage {
 public:
  GrayImage() = default;
  GrayImage(int width, int height) { allocate(width, height); }
  void allocate(int width, int height) {
    width_ = width;
    height_ = height;
    pixels_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
  }
  [[nodiscard]] GrayView view() const { return {pixels_.data(), width_, height_, width_}; }
  [[nodiscard]] std::uint8_t* data() { return pixels_.data(); }
  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }

 private:
  std::vector<std::uint8_t> pixels_;
  int width_ = 0, height_ = 0;
};

/// Levels of halved resolution; level 0 is a copy of the input. Buffers are allocated in the
/// constructor; build() never allocates.
class Pyramid {
 public:
  Pyramid() = default;
  Pyramid(int width, int height, int levels);
  /// Copies `image` (its size must match) into level 0 and halves it down (2x2 mean).
  void build(const GrayView& image);
  [[nodiscard]] int levels() const { return static_cast<int>(levels_.size()); }
  [[nodiscard]] GrayView level(int i) const { return levels_[static_cast<std::size_t>(i)].view(); }

 private:
  std::vector<GrayImage> levels_;
};

/// A remap table (bilinear, fixed point) computed once from float maps such as OpenCV's
/// initUndistortRectifyMap; apply() writes the remapped image with no allocation. Pixels whose
/// source falls outside the input (or on its last row or column) are black. A table that is the
/// identity (an already rectified rig) copies rows; any other runs the SIMD gather kernel
/// (remap_kernel.hpp), with the same bytes as the scalar reference.
class RemapTable {
 public:
  RemapTable() = default;
  /// map_x/map_y: source coordinates for each destination pixel, row-major width x height.
  RemapTable(int width, int height, std::span<const float> map_x, std::span<const float> map_y,
             int source_width, int source_height);
  void apply(const GrayView& source, std::uint8_t* out) const;
  /// The output pixels [first, first + count) (row-major: y * width + x) only, with the bytes
  /// apply() gives them; the rest of `out` is left alone. For rectifying on demand the part of
  /// an image a search reads. `first + count` must not pass width * height.
  void apply_span(const GrayView& source, std::uint8_t* out, std::size_t first,
                  std::size_t count) const;
  /// The same through the scalar reference only (tests and benchmarks compare the two).
  void apply_scalar(const GrayView& source, std::uint8_t* out) const;
  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }
  /// True when every pixel is its own source (within 1/256 px): apply() copies.
  [[nodiscard]] bool identity() const { return identity_; }

 private:
  void check(const GrayView& source) const;
  /// Per destination pixel: (y << 16) | x of the top-left source tap, and the four bilinear
  /// weights in 1/128 (top-left, top-right, bottom-left, bottom-right; summing to 128) packed
  /// in bytes. Outside: pos 0, weights 0.
  std::vector<std::uint32_t> pos_, weights_;
  /// Per kRemapChunk taps: 1 when one of them reads past the source's last bytes four at a
  /// time (its bottom-right corner), so the chunk takes the scalar path.
  std::vector<std::uint8_t> chunk_scalar_;
  bool identity_ = false;
  std::vector<std::uint32_t> black_;  //!< the identity's pixels without a tap
  int width_ = 0, height_ = 0, source_width_ = 0, source_height_ = 0;
};

}  // namespace wallar::dsp
