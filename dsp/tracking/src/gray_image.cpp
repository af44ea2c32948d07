// SPDX-License-Identifier: Apache-2.0
/// @file gray_image.cpp
/// @brief Pyramid halving and the fixed-point remap.
#include "wallar/dsp/tracking/gray_image.hpp"

#include <cmath>
#include <algorithm>
#include <cstring>
#include <stdexcept>

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
  taps_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const float x = map_x[i], y = map_y[i];
    if (!(x >= 0.0f && y >= 0.0f && x < static_cast<float>(source_width - 1) &&
          y < static_cast<float>(source_height - 1))) {
      continue;
    }
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    Tap& t = taps_[i];
    t.x = static_cast<std::int16_t>(x0);
    t.y = static_cast<std::int16_t>(y0);
    t.wx = static_cast<std::uint8_t>(std::lround((x - static_cast<float>(x0)) * 128.0f));
    t.wy = static_cast<std::uint8_t>(std::lround((y - static_cast<float>(y0)) * 128.0f));
  }
}

void RemapTable::apply(const GrayView& source, std::uint8_t* out) const {
  if (source.width != source_width_ || source.height != source_height_) {
    throw std::invalid_argument("remap: the image size does not match the calibration");
  }
  for (int y = 0; y < height_; ++y) {
    const Tap* taps = taps_.data() + std::ptrdiff_t{y} * width_;
    std::uint8_t* dst = out + std::ptrdiff_t{y} * width_;
    for (int x = 0; x < width_; ++x) {
      const Tap t = taps[x];
      if (t.x < 0) {
        dst[x] = 0;
        continue;
      }
      const std::uint8_t* r0 = source.row(t.y) + t.x;
      const std::uint8_t* r1 = r0 + source.stride;
      const int wx = t.wx, wy = t.wy;
      const int top = r0[0] * (128 - wx) + r0[1] * wx;
      const int bottom = r1[0] * (128 - wx) + r1[1] * wx;
      dst[x] = static_cast<std::uint8_t>((top * (128 - wy) + bottom * wy + 8192) >> 14);
    }
  }
}

}  // namespace wallar::dsp
