// SPDX-License-Identifier: Apache-2.0
/// @file gray_image.cpp
/// @brief Pyramid halving and the fixed-point remap.
#include "wallar/dsp/tracking/gray_image.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "wallar/dsp/tracking/remap_kernel.hpp"

namespace wallar::dsp {

Pyramid::Pyramid(int width, int height, int levels) {
  if (width <= 0 || height <= 0 || levels < 1) {
    throw std::invalid_argument("pyramid: size and level count must be positive");
  }
  levels_.resize(static_cast<std::size_t>(levels));
  for (GrayImage& level : levels_) {
    level.allocate(width, height);
    width = (width + 1) / 2;
    height = (height + 1) / 2;
  }
}

void Pyramid::build(const GrayView& image) {
  GrayImage& base = levels_[0];
  for (int y = 0; y < base.height(); ++y) {
    std::memcpy(base.data() + std::ptrdiff_t{y} * base.width(), image.row(y),
                static_cast<std::size_t>(base.width()));
  }
  for (std::size_t i = 1; i < levels_.size(); ++i) {
    const GrayView src = levels_[i - 1].view();
    GrayImage& dst = levels_[i];
    for (int y = 0; y < dst.height(); ++y) {
      const std::uint8_t* r0 = src.row(std::min(2 * y, src.height - 1));
      const std::uint8_t* r1 = src.row(std::min(2 * y + 1, src.height - 1));
      std::uint8_t* out = dst.data() + std::ptrdiff_t{y} * dst.width();
      for (int x = 0; x < dst.width(); ++x) {
        const int x0 = std::min(2 * x, src.width - 1), x1 = std::min(2 * x + 1, src.width - 1);
        out[x] = static_cast<std::uint8_t>((r0[x0] + r0[x1] + r1[x0] + r1[x1] + 2) >> 2);
      }
    }
  }
}

RemapTable::RemapTable(int width, int height, std::span<const float> map_x,
                       std::span<const float> map_y, int source_width, int source_height)
    : width_(width), height_(height), source_width_(source_width), source_height_(source_height) {
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  if (map_x.size() != n || map_y.size() != n) {
    throw std::invalid_argument("remap table: the maps are not width x height");
  }
  if (source_width > 32767 || source_height > 32767 || source_width < 4 || source_height < 2) {
    throw std::invalid_argument("remap table: the source is not 4x2 to 32767x32767 pixels");
  }
  pos_.assign(n, 0);
  weights_.assign(n, 0);
  chunk_scalar_.assign((n + kRemapChunk - 1) / kRemapChunk, 0);
  identity_ = width == source_width && height == source_height;
  black_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const int col = static_cast<int>(i % static_cast<std::size_t>(width));
    const int row = static_cast<int>(i / static_cast<std::size_t>(width));
    const float x = map_x[i], y = map_y[i];
    if (!(x >= 0.0f && y >= 0.0f && x < static_cast<float>(source_width - 1) &&
          y < static_cast<float>(source_height - 1))) {
      // Black (on the identity: the last column and row, or a border pixel a rounding error
      // outside).
      identity_ = identity_ && std::abs(x - static_cast<float>(col)) < 1.0f / 256 &&
                  std::abs(y - static_cast<float>(row)) < 1.0f / 256;
      if (identity_) black_.push_back(static_cast<std::uint32_t>(i));
      continue;
    }
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    // Weights in 1/128 that sum to exactly 128 (the largest absorbs the rounding).
    const float ax = x - static_cast<float>(x0), ay = y - static_cast<float>(y0);
    const std::array<float, 4> wf{(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
    std::array<int, 4> w{};
    int sum = 0;
    std::size_t largest = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      w[k] = static_cast<int>(std::lround(wf[k] * 128.0f));
      sum += w[k];
      if (wf[k] > wf[largest]) largest = k;
    }
    w[largest] += 128 - sum;
    pos_[i] = (static_cast<std::uint32_t>(y0) << 16) | static_cast<std::uint32_t>(x0);
    weights_[i] = static_cast<std::uint32_t>(w[0]) | static_cast<std::uint32_t>(w[1]) << 8 |
                  static_cast<std::uint32_t>(w[2]) << 16 | static_cast<std::uint32_t>(w[3]) << 24;
    // The identity: one weight of 128, on the pixel (col, row) itself.
    const std::size_t whole =
        static_cast<std::size_t>(std::find(w.begin(), w.end(), 128) - w.begin());
    identity_ = identity_ && whole < 4 && x0 + static_cast<int>(whole & 1) == col &&
                y0 + static_cast<int>(whole >> 1) == row;
    // The kernel reads bytes x0 .. x0 + 3 of rows y0 and y0 + 1: past the buffer's end for the
    // last row's last three pixels when rows are packed.
    if (y0 == source_height - 2 && x0 > source_width - 4) chunk_scalar_[i / kRemapChunk] = 1;
  }
  if (!identity_) black_ = {};
}

void RemapTable::check(const GrayView& source) const {
  if (source.width != source_width_ || source.height != source_height_) {
    throw std::invalid_argument("remap: the image size does not match the calibration");
  }
}

void RemapTable::apply(const GrayView& source, std::uint8_t* out) const {
  apply_span(source, out, 0, pos_.size());
}

void RemapTable::apply_span(const GrayView& source, std::uint8_t* out, std::size_t first,
                            std::size_t count) const {
  check(source);
  const std::size_t end = first + count;
  if (end > pos_.size()) throw std::invalid_argument("remap: span past the image");
  if (identity_) {
    // What the taps give: each pixel itself (rows of the source), those on the last column and
    // row without a tap black (black_ is in pixel order).
    for (std::size_t i = first; i < end;) {
      const std::size_t row = i / static_cast<std::size_t>(width_);
      const std::size_t row_end = std::min(end, (row + 1) * static_cast<std::size_t>(width_));
      std::memcpy(out + i, source.row(static_cast<int>(row)) + (i - row * width_), row_end - i);
      i = row_end;
    }
    for (auto it = std::lower_bound(black_.begin(), black_.end(), first);
         it != black_.end() && *it < end; ++it) {
      out[*it] = 0;
    }
    return;
  }
  // Through the kernel, but the chunks flagged as reading past the source's end (its
  // bottom-right corner) through the scalar reference (the same bytes).
  std::size_t i = first;
  while (i < end) {
    const std::size_t c = i / kRemapChunk;
    std::size_t e = c;  // the chunks from c on that the kernel may read
    while (e * kRemapChunk < end && chunk_scalar_[e] == 0) ++e;
    if (e > c) {
      const std::size_t stop = std::min(end, e * kRemapChunk);
      remap_taps(source.data, source.stride, pos_.data() + i, weights_.data() + i, stop - i,
                 out + i);
      i = stop;
    } else {
      const std::size_t stop = std::min(end, (c + 1) * kRemapChunk);
      remap_taps_scalar(source.data, source.stride, pos_.data() + i, weights_.data() + i, stop - i,
                        out + i);
      i = stop;
    }
  }
}

void RemapTable::apply_scalar(const GrayView& source, std::uint8_t* out) const {
  check(source);
  remap_taps_scalar(source.data, source.stride, pos_.data(), weights_.data(), pos_.size(), out);
}

}  // namespace wallar::dsp
