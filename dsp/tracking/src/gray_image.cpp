// SPDX-License-Identifier: Apache-2.0
/// @file gray_image.cpp
/// @brief Pyramid halving and the fixed-point remap.
#include "wallar/dsp/tracking/gray_image.hpp"

#include <algorithm>
#include <cmath>
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
  if (source_width > 32767 || source_height > 32767) {
    throw std::invalid_argument("remap table: the source is larger than 32767 pixels");
  }
  taps_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const float x = map_x[i], y = map_y[i];
    if (!(x >= 0.0f && y >= 0.0f && x < static_cast<float>(source_width - 1) &&
          y < static_cast<float>(source_height - 1))) {
      continue;
    }
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    // Weights in 1/128 that sum to exactly 128 (the largest absorbs the rounding).
    const float ax = x - static_cast<float>(x0), ay = y - static_cast<float>(y0);
    const std::array<float, 4> wf{(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
    Tap& t = taps_[i];
    t.x = static_cast<std::int16_t>(x0);
    t.y = static_cast<std::int16_t>(y0);
    int sum = 0;
    std::size_t largest = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      t.w[k] = static_cast<std::uint8_t>(std::lround(wf[k] * 128.0f));
      sum += t.w[k];
      if (wf[k] > wf[largest]) largest = k;
    }
    t.w[largest] = static_cast<std::uint8_t>(t.w[largest] + (128 - sum));
  }
}

void RemapTable::apply(const GrayView& source, std::uint8_t* out) const {
  if (source.width != source_width_ || source.height != source_height_) {
    throw std::invalid_argument("remap: the image size does not match the calibration");
  }
  const std::uint8_t* src = source.data;
  const std::ptrdiff_t stride = source.stride;
  const std::size_t n = taps_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Tap t = taps_[i];
    if (t.x < 0) {
      out[i] = 0;
      continue;
    }
    const std::uint8_t* p = src + t.y * stride + t.x;
    out[i] = static_cast<std::uint8_t>(
        (p[0] * t.w[0] + p[1] * t.w[1] + p[stride] * t.w[2] + p[stride + 1] * t.w[3] + 64) >> 7);
  }
}

}  // namespace wallar::dsp
