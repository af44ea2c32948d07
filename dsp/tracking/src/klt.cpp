// SPDX-License-Identifier: Apache-2.0
/// @file klt.cpp
/// @brief Coarse-to-fine translational Lucas-Kanade.
#include "wallar/dsp/tracking/klt.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <span>

namespace wallar::dsp {
namespace {
constexpr int kMaxHalf = 10;
constexpr std::size_t kMaxWindow = (2 * kMaxHalf + 1) * (2 * kMaxHalf + 1);
constexpr std::size_t kMaxGrid = (2 * kMaxHalf + 3) * (2 * kMaxHalf + 3);

/// Full-resolution pixel coordinate to level `level` (2x2-mean pyramids: pixel centres shift).
float to_level(float x, int level) { return (x + 0.5f) / static_cast<float>(1 << level) - 0.5f; }
float from_level(float x, int level) { return (x + 0.5f) * static_cast<float>(1 << level) - 0.5f; }
}  // namespace

Brightness estimate_brightness(std::span<float> prev_samples, std::span<float> cur_samples,
                               float min_change) {
  Brightness out;
  const std::size_t n = std::min(prev_samples.size(), cur_samples.size());
  if (n < 16) return out;
  // Medians and median absolute deviations: robust to the samples whose prediction was wrong.
  const auto median = [](std::span<float> v) {
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
  };
  const std::span<float> a = prev_samples.first(n), b = cur_samples.first(n);
  const float ma = median(a), mb = median(b);
  for (float& x : a) x = std::abs(x - ma);
  for (float& x : b) x = std::abs(x - mb);
  const float sa = median(a), sb = median(b);
  if (!(sa > 0.5f) || !(sb > 0.5f)) return out;
  const float gain = std::clamp(sb / sa, 1.0f / 3.0f, 3.0f);
  const float bias = mb - gain * ma;
  // Small differences are the scene, not the exposure: left alone.
  if (std::abs(gain - 1.0f) < min_change && std::abs(mb - ma) < 255.0f * min_change) return out;
  out.gain = gain;
  out.bias = bias;
  return out;
}

bool klt_track(const Pyramid& prev, const Pyramid& cur, float u0, float v0, float& u, float& v,
               const KltParams& params, const Brightness& brightness) {
  const int hw = params.half_window > kMaxHalf ? kMaxHalf : params.half_window;
  const float border = static_cast<float>(hw + 2);
  std::array<float, kMaxWindow> tmpl, gx, gy;
  std::array<float, kMaxGrid> grid;
  float mean_abs = 0.0f;
  // The frames' brightness relation (an exposure or gain step), held for every window.
  const float gain = std::clamp(brightness.gain, 1.0f / 3.0f, 3.0f), bias = brightness.bias;
  for (int level = prev.levels() - 1; level >= 0; --level) {
    const GrayView P = prev.level(level), C = cur.level(level);
    const float px = to_level(u0, level), py = to_level(v0, level);
    float qx = to_level(u, level), qy = to_level(v, level);
    if (!P.inside(px, py, border)) {
      if (level == 0) return false;
      continue;  // too close to the border at this scale: refine on the finer levels only
    }
    // Template and its gradients (central differences) from the previous image: one grid a
    // pixel wider on each side than the window.
    const int side = 2 * hw + 3;
    P.sample_grid(px - static_cast<float>(hw + 1), py - static_cast<float>(hw + 1), side, side,
                  grid.data());
    float a = 0.0f, b = 0.0f, c = 0.0f;
    std::size_t k = 0;
    for (int dy = -hw; dy <= hw; ++dy) {
      const float* g = grid.data() + static_cast<std::ptrdiff_t>(dy + hw + 1) * side + hw + 1;
      for (int dx = -hw; dx <= hw; ++dx, ++k) {
        tmpl[k] = g[dx];
        gx[k] = 0.5f * (g[dx + 1] - g[dx - 1]);
        gy[k] = 0.5f * (g[dx + side] - g[dx - side]);
        a += gx[k] * gx[k];
        b += gx[k] * gy[k];
        c += gy[k] * gy[k];
      }
    }
    const float n = static_cast<float>(k);
    const float det = a * c - b * b;
    const float h = 0.5f * (a - c);
    const float min_eig = (0.5f * (a + c) - std::sqrt(h * h + b * b)) / n;
    if (min_eig < params.min_eigen || !(std::abs(det) > 1e-9f)) return false;
    for (int it = 0; it < params.max_iterations; ++it) {
      if (!C.inside(qx, qy, border)) return false;
      float ex = 0.0f, ey = 0.0f;
      mean_abs = 0.0f;
      C.sample_grid(qx - static_cast<float>(hw), qy - static_cast<float>(hw), 2 * hw + 1,
                    2 * hw + 1, grid.data());
      for (std::size_t i = 0; i < k; ++i) {
        const float e = grid[i] - (gain * tmpl[i] + bias);
        ex += e * gx[i];
        ey += e * gy[i];
        mean_abs += std::abs(e);
      }
      mean_abs /= n * gain;  // in the template's grey levels
      // The template's gradients scale with the gain too.
      const float sx = (c * ex - b * ey) / (det * gain), sy = (a * ey - b * ex) / (det * gain);
      qx -= sx;
      qy -= sy;
      if (sx * sx + sy * sy < params.epsilon_px * params.epsilon_px) break;
    }
    u = from_level(qx, level);
    v = from_level(qy, level);
  }
  return std::isfinite(u) && std::isfinite(v) && mean_abs <= params.max_mean_abs;
}

}  // namespace wallar::dsp
