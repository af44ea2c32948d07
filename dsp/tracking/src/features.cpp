// SPDX-License-Identifier: Apache-2.0
/// @file features.cpp
/// @brief Segment-test corners, Shi-Tomasi ranking, bucketing, row stereo matching, patches.
#include "wallar/dsp/tracking/features.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "wallar/core/hash.hpp"
#include "wallar/dsp/tracking/patch_cost.hpp"
#include "wallar/dsp/tracking/row_zsad.hpp"
#include "wallar/dsp/tracking/segment_prefilter.hpp"

namespace wallar::dsp {
namespace {

/// The 16 pixels of the radius-3 Bresenham circle, clockwise from the top.
constexpr std::array<std::array<int, 2>, 16> kCircle{{{0, -3},
                                                      {1, -3},
                                                      {2, -2},
                                                      {3, -1},
                                                      {3, 0},
                                                      {3, 1},
                                                      {2, 2},
                                                      {1, 3},
                                                      {0, 3},
                                                      {-1, 3},
                                                      {-2, 2},
                                                      {-3, 1},
                                                      {-3, 0},
                                                      {-3, -1},
                                                      {-2, -2},
                                                      {-1, -3}}};

/// True when the 16-bit ring mask has 9 contiguous set bits (with wrap-around).
bool has_arc9(std::uint32_t mask16) {
  std::uint32_t m = mask16 | (mask16 << 16);
  std::uint32_t run = m;
  for (int k = 1; k < 9; ++k) run &= m >> k;
  return run != 0;
}

/// Segment-test score at (x, y): 0 when not a corner, else the summed contrast beyond t of the
/// ring pixels on the winning side.
std::int16_t segment_test(const GrayView& img, int x, int y, int t) {
  const std::uint8_t* p = img.row(y) + x;
  const int c = p[0];
  const int hi = c + t, lo = c - t;
  const std::ptrdiff_t s = img.stride;
  const int top = p[-3 * s], bottom = p[3 * s], right = p[3], left = p[-3];
  const int bright = (top > hi) + (bottom > hi) + (right > hi) + (left > hi);
  const int dark = (top < lo) + (bottom < lo) + (right < lo) + (left < lo);
  if (bright < 2 && dark < 2) return 0;
  std::uint32_t bright_mask = 0, dark_mask = 0;
  int bright_sum = 0, dark_sum = 0;
  for (int i = 0; i < 16; ++i) {
    const int v =
        p[kCircle[static_cast<std::size_t>(i)][1] * s + kCircle[static_cast<std::size_t>(i)][0]];
    if (v > hi) {
      bright_mask |= 1u << i;
      bright_sum += v - hi;
    } else if (v < lo) {
      dark_mask |= 1u << i;
      dark_sum += lo - v;
    }
  }
  int score = 0;
  if (has_arc9(bright_mask)) score = bright_sum;
  if (has_arc9(dark_mask)) score = std::max(score, dark_sum);
  if (score == 0 && (has_arc9(bright_mask) || has_arc9(dark_mask))) score = 1;
  return static_cast<std::int16_t>(std::min(score, 32767));
}

/// Vertex offset of the parabola through (-1, a), (0, b), (1, c), clamped to +-0.5.
float parabola_peak(float a, float b, float c) {
  const float den = a - 2.0f * b + c;
  if (!(den > 1e-6f)) return 0.0f;
  return std::clamp(0.5f * (a - c) / den, -0.5f, 0.5f);
}

/// Sub-pixel disparity by Gauss-Newton on the horizontal shift (zero-mean intensities, so an
/// offset between the cameras' exposures does not bias it), from the integer match's parabola
/// estimate. The SAD parabola locks toward whole pixels; this does not. Returns the refined
/// disparity, or `d0` when the refinement leaves +-1 px of it or the window has no gradient.
/// What a row search covers: its window's half size, the left pixel, and the disparity range
/// kept inside the row and the kernel's 512 candidates (match_along_row and the footprint it
/// reads, match_along_row_reads, from the same numbers).
struct RowSearch {
  int hw, xl, y, d_min, d_max;
};
RowSearch row_search_of(float u_px, float v_px, int d_min, int d_max,
                        const StereoMatchParams& params) {
  RowSearch r;
  r.hw = std::clamp(params.half_window, 1, kRowZsadMaxHalfWindow);
  r.xl = static_cast<int>(std::lround(u_px));
  r.y = static_cast<int>(std::lround(v_px));
  r.d_min = std::max(d_min, 0);
  r.d_max = std::min({d_max, r.xl - r.hw - 1, r.d_min + 511});
  return r;
}

float refine_disparity(const GrayView& left, const GrayView& right, float u_px, int y, int hw,
                       float d0) {
  constexpr int kHw = 4;  // 9x9 window for the refinement
  (void)hw;
  // Bilinear samples read the row below theirs: the window's last row must not be the image's.
  if (y - kHw < 0 || y + kHw + 1 >= left.height || y + kHw + 1 >= right.height) return d0;
  constexpr int kSide = 2 * kHw + 1;
  {
    const float first = u_px - static_cast<float>(kHw), last = u_px + static_cast<float>(kHw);
    if (first < 1.0f || last >= static_cast<float>(left.width) - 2.0f) return d0;
  }
  std::array<float, kSide * kSide> tmpl{};
  left.sample_grid(u_px - static_cast<float>(kHw), static_cast<float>(y - kHw), kSide, kSide,
                   tmpl.data());
  float mean_l = 0.0f;
  for (const float v : tmpl) mean_l += v;
  const float n = static_cast<float>(tmpl.size());
  mean_l /= n;
  float d = d0;
  // The right window with a column more on each side for the central differences.
  std::array<float, (kSide + 2) * kSide> grid{};
  for (int it = 0; it < 6; ++it) {
    float mean_r = 0.0f, sum_g = 0.0f, sum_gg = 0.0f, sum_ge = 0.0f, sum_e = 0.0f;
    std::array<float, kSide * kSide> rv{}, gv{};
    const float first = u_px - d - static_cast<float>(kHw);
    if (first < 2.0f ||
        first + static_cast<float>(2 * kHw) >= static_cast<float>(right.width) - 3.0f) {
      return d0;
    }
    right.sample_grid(first - 1.0f, static_cast<float>(y - kHw), kSide + 2, kSide, grid.data());
    std::size_t k = 0;
    for (int r = 0; r < kSide; ++r) {
      const float* g = grid.data() + static_cast<std::ptrdiff_t>(r) * (kSide + 2) + 1;
      for (int c = 0; c < kSide; ++c, ++k) {
        rv[k] = g[c];
        gv[k] = 0.5f * (g[c + 1] - g[c - 1]);
        mean_r += rv[k];
      }
    }
    mean_r /= n;
    for (std::size_t i = 0; i < k; ++i) {
      const float e = (rv[i] - mean_r) - (tmpl[i] - mean_l);
      sum_g += gv[i];
      sum_gg += gv[i] * gv[i];
      sum_ge += gv[i] * e;
      sum_e += e;
    }
    // Zero-mean gradients (the mean is removed from the residual too).
    const float gg = sum_gg - sum_g * sum_g / n;
    if (!(gg > 1e-3f * n)) return d0;
    // r(d) = R(u - d) - L, dr/dd = -g: the Gauss-Newton step is +sum(g e) / sum(g g).
    const float step = (sum_ge - sum_g * sum_e / n) / gg;
    d += step;
    if (std::abs(d - d0) > 1.0f || !std::isfinite(d)) return d0;
    if (std::abs(step) < 0.005f) break;
  }
  return d;
}

}  // namespace

CornerDetector::CornerDetector(int width, int height, const DetectorParams& params)
    : params_(params),
      width_(width),
      height_(height),
      cols_((width + params.bucket_px - 1) / params.bucket_px),
      rows_((height + params.bucket_px - 1) / params.bucket_px),
      threshold_(params.threshold) {
  if (width <= 2 * params.border_px || height <= 2 * params.border_px || params.bucket_px <= 0 ||
      params.per_bucket <= 0 || params.border_px < 4) {
    throw std::invalid_argument("corner detector: image too small or bad bucket settings");
  }
  score_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
  candidate_.assign(static_cast<std::size_t>(width), 0);
  bucket_best_.resize(static_cast<std::size_t>(cols_ * rows_ * params.per_bucket));
  bucket_n_.resize(static_cast<std::size_t>(cols_ * rows_));
}

int CornerDetector::bucket_of(float u_px, float v_px) const {
  const int c = std::clamp(static_cast<int>(u_px) / params_.bucket_px, 0, cols_ - 1);
  const int r = std::clamp(static_cast<int>(v_px) / params_.bucket_px, 0, rows_ - 1);
  return r * cols_ + c;
}

void CornerDetector::detect(const GrayView& image, std::span<const std::uint16_t> occupancy,
                            FixedVector<Corner>& out) {
  if (image.width != width_ || image.height != height_) {
    throw std::invalid_argument("corner detector: the image size does not match");
  }
  if (occupancy.size() != static_cast<std::size_t>(bucket_count())) {
    throw std::invalid_argument("corner detector: occupancy needs one entry per bucket");
  }
  out.clear();
  const int b = params_.border_px;
  std::fill(score_.begin(), score_.end(), std::int16_t{0});
  // The compass pre-filter for a whole row in SIMD, the full segment test on its candidates.
  for (int y = b; y < height_ - b; ++y) {
    std::int16_t* srow = score_.data() + std::ptrdiff_t{y} * width_;
    segment_candidates(image.row(y) + b, image.stride, width_ - 2 * b, threshold_,
                       candidate_.data());
    for (int x = b; x < width_ - b; ++x) {
      if (candidate_[static_cast<std::size_t>(x - b)] != 0) {
        srow[x] = segment_test(image, x, y, threshold_);
      }
    }
  }
  std::fill(bucket_n_.begin(), bucket_n_.end(), std::uint8_t{0});
  int raw = 0;
  const int k = params_.per_bucket;
  for (int y = b; y < height_ - b; ++y) {
    const std::int16_t* s0 = score_.data() + std::ptrdiff_t{y} * width_;
    for (int x = b; x < width_ - b; ++x) {
      const std::int16_t s = s0[x];
      if (s == 0) continue;
      // 3x3 non-maximum suppression: strictly above the neighbours before, at least the ones after.
      const std::int16_t* up = s0 - width_;
      const std::int16_t* down = s0 + width_;
      if (!(s > up[x - 1] && s > up[x] && s > up[x + 1] && s > s0[x - 1] && s >= s0[x + 1] &&
            s >= down[x - 1] && s >= down[x] && s >= down[x + 1])) {
        continue;
      }
      ++raw;
      const int bucket = bucket_of(static_cast<float>(x), static_cast<float>(y));
      const int room = k - static_cast<int>(occupancy[static_cast<std::size_t>(bucket)]);
      if (room <= 0) continue;
      const float st = shi_tomasi_score(image, x, y);
      if (st < params_.min_shi_tomasi) continue;
      Corner* best = bucket_best_.data() + static_cast<std::ptrdiff_t>(bucket) * k;
      int n = bucket_n_[static_cast<std::size_t>(bucket)];
      if (n == room && best[n - 1].shi_tomasi >= st) continue;
      if (n < room) ++n;
      int i = n - 1;  // insertion into the sorted slots, dropping the weakest when full
      while (i > 0 && best[i - 1].shi_tomasi < st) {
        best[i] = best[i - 1];
        --i;
      }
      best[i] = Corner{static_cast<float>(x), static_cast<float>(y), st};
      bucket_n_[static_cast<std::size_t>(bucket)] = static_cast<std::uint8_t>(n);
    }
  }
  for (int bucket = 0; bucket < bucket_count(); ++bucket) {
    const Corner* best = bucket_best_.data() + static_cast<std::ptrdiff_t>(bucket) * k;
    for (int i = 0; i < bucket_n_[static_cast<std::size_t>(bucket)]; ++i) {
      if (!out.push_back(best[i])) break;
    }
  }
  last_raw_ = raw;
  // Adapt the threshold toward the target count (dark or blank frames lower it, busy ones raise).
  const int step = std::max(1, threshold_ / 5);
  if (raw < params_.target_raw_corners / 2) {
    threshold_ = std::max(params_.threshold_min, threshold_ - step);
  } else if (raw > 2 * params_.target_raw_corners) {
    threshold_ = std::min(params_.threshold_max, threshold_ + step);
  }
}

float shi_tomasi_score(const GrayView& image, int x, int y, int half) {
  float a = 0.0f, bb = 0.0f, c = 0.0f;
  for (int dy = -half; dy <= half; ++dy) {
    const std::uint8_t* r = image.row(y + dy) + x;
    const std::uint8_t* ru = r - image.stride;
    const std::uint8_t* rd = r + image.stride;
    for (int dx = -half; dx <= half; ++dx) {
      const float gx = 0.5f * (static_cast<float>(r[dx + 1]) - static_cast<float>(r[dx - 1]));
      const float gy = 0.5f * (static_cast<float>(rd[dx]) - static_cast<float>(ru[dx]));
      a += gx * gx;
      bb += gx * gy;
      c += gy * gy;
    }
  }
  const float n = static_cast<float>((2 * half + 1) * (2 * half + 1));
  a /= n;
  bb /= n;
  c /= n;
  const float h = 0.5f * (a - c);
  return 0.5f * (a + c) - std::sqrt(h * h + bb * bb);
}

std::optional<float> match_along_row(const GrayView& left, const GrayView& right, float u_px,
                                     float v_px, int d_min_px, int d_max_px,
                                     const StereoMatchParams& params) {
  const auto [hw, xl, y, d_min, d_max] = row_search_of(u_px, v_px, d_min_px, d_max_px, params);
  if (y - hw - 1 < 0 || y + hw + 1 >= left.height || xl - hw < 0 || xl + hw >= left.width) {
    return std::nullopt;
  }
  if (d_max - d_min < 2) return std::nullopt;
  // Integer costs (n^2 times the zero-mean SAD per pixel) from the SIMD row kernel: the
  // candidates x = xl - d_max .. xl - d_min of the right row, so cost index d_max - d.
  const int count = d_max - d_min + 1;
  const float per_px =
      1.0f / static_cast<float>((2 * hw + 1) * (2 * hw + 1) * (2 * hw + 1) * (2 * hw + 1));
  std::array<std::uint32_t, 512> by_x;  // written before read: no 2 KB clear per call
  row_zsad(left.row(y) + xl, left.stride, right.row(y) + (xl - d_max), right.stride, hw, count,
           by_x.data());
  std::array<float, 512> cost;  // likewise
  int best = -1;
  for (int d = d_min; d <= d_max; ++d) {
    const float c = static_cast<float>(by_x[static_cast<std::size_t>(d_max - d)]) * per_px;
    cost[static_cast<std::size_t>(d - d_min)] = c;
    if (best < 0 || c < cost[static_cast<std::size_t>(best - d_min)]) best = d;
  }
  const float c0 = cost[static_cast<std::size_t>(best - d_min)];
  if (c0 > params.max_cost_per_px || best == d_min || best == d_max) return std::nullopt;
  float second = std::numeric_limits<float>::infinity();
  for (int d = d_min; d <= d_max; ++d) {
    if (std::abs(d - best) > 1)
      second = std::min(second, cost[static_cast<std::size_t>(d - d_min)]);
  }
  if (c0 > params.uniqueness * second) return std::nullopt;
  // Left-right check: the right patch, searched back along the left row (x = xr + d_min ..),
  // lands where we began.
  const int xr = xl - best;
  const int back_count = std::min(d_max, left.width - 1 - hw - xr) - d_min + 1;
  if (back_count < 1) return std::nullopt;
  row_zsad(right.row(y) + xr, right.stride, left.row(y) + (xr + d_min), left.stride, hw, back_count,
           by_x.data());
  int back = -1;
  std::uint32_t back_cost = 0;
  for (int i = 0; i < back_count; ++i) {
    if (back < 0 || by_x[static_cast<std::size_t>(i)] < back_cost) {
      back = d_min + i;
      back_cost = by_x[static_cast<std::size_t>(i)];
    }
  }
  if (back < 0 || static_cast<float>(std::abs(back - best)) > params.lr_tolerance_px) {
    return std::nullopt;
  }
  const std::size_t i = static_cast<std::size_t>(best - d_min);
  float disparity = static_cast<float>(best) + parabola_peak(cost[i - 1], cost[i], cost[i + 1]) +
                    (u_px - static_cast<float>(xl));
  if (params.subpixel_refine) disparity = refine_disparity(left, right, u_px, y, hw, disparity);
  if (disparity < params.min_disparity_px) return std::nullopt;
  return disparity;
}

PixelRect match_along_row_reads(int width, int height, float u_px, float v_px, int d_min_px,
                                int d_max_px, const StereoMatchParams& params) {
  const auto [hw, xl, y, d_min, d_max] = row_search_of(u_px, v_px, d_min_px, d_max_px, params);
  // The row kernels read xl - d_max - hw .. xl - d_min + hw over rows y +- hw. The refinement
  // (9x9, its disparity within 1 px of the match's, itself within 1 px of [d_min, d_max]) reads
  // a column more on each side and their bilinear neighbours: xl - d_max - 8 .. xl - d_min + 8,
  // rows y - 4 .. y + 5. One pixel more on each side for rounding.
  const int cols = std::max(hw, 8) + 1, rows = std::max(hw, 4);
  PixelRect r;
  r.x0 = std::clamp(xl - d_max - cols, 0, width);
  r.x1 = std::clamp(xl - d_min + cols + 1, 0, width);
  r.y0 = std::clamp(y - rows - 1, 0, height);
  r.y1 = std::clamp(y + rows + 3, 0, height);
  return r;
}

bool extract_patch(const GrayView& image, float u_px, float v_px, Patch8& out) {
  const int x = static_cast<int>(std::lround(u_px)), y = static_cast<int>(std::lround(v_px));
  if (x < 4 || y < 4 || x + 4 > image.width || y + 4 > image.height) return false;
  for (int r = 0; r < 8; ++r) {
    std::memcpy(out.px + 8 * r, image.row(y - 4 + r) + (x - 4), 8);
  }
  return true;
}

std::optional<std::pair<float, float>> search_patch(const GrayView& image, const Patch8& patch,
                                                    float u_px, float v_px, int radius,
                                                    float* cost) {
  constexpr int kMaxRadius = 48;
  radius = std::clamp(radius, 1, kMaxRadius);
  const int cx = static_cast<int>(std::lround(u_px)), cy = static_cast<int>(std::lround(v_px));
  const int x0 = std::max(cx - radius, 5), x1 = std::min(cx + radius, image.width - 5);
  const int y0 = std::max(cy - radius, 5), y1 = std::min(cy + radius, image.height - 5);
  if (x1 - x0 < 2 || y1 - y0 < 2) return std::nullopt;
  // Zero-mean, gain-normalised SAD: the window's deviations are scaled to the patch's contrast,
  // so an exposure or gain change since the key-frame does not count as a mismatch, while a
  // window without texture (a dark frame, a blank wall) cannot match a textured patch.
  std::array<float, 64> p{};
  float patch_mean = 0.0f;
  for (std::size_t i = 0; i < 64; ++i) patch_mean += patch.px[i];
  patch_mean /= 64.0f;
  float patch_mad = 0.0f;
  for (std::size_t i = 0; i < 64; ++i) {
    p[i] = static_cast<float>(patch.px[i]) - patch_mean;
    patch_mad += std::abs(p[i]);
  }
  patch_mad /= 64.0f;
  if (!(patch_mad > 0.5f)) return std::nullopt;  // a flat patch matches anything
  std::array<float, (2 * kMaxRadius + 1) * (2 * kMaxRadius + 1)> costs;  // 37 KB of stack
  const int w = x1 - x0 + 1;
  for (int y = y0; y <= y1; ++y) {
    patch_costs_row(p.data(), patch_mad, image.row(y - 4) + (x0 - 4), image.stride, w,
                    costs.data() + static_cast<std::ptrdiff_t>(y - y0) * w);
  }
  int best_x = x0, best_y = y0;
  float best = std::numeric_limits<float>::infinity();
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const float c = costs[static_cast<std::size_t>((y - y0) * w + (x - x0))];
      if (c < best) {
        best = c;
        best_x = x;
        best_y = y;
      }
    }
  }
  if (!std::isfinite(best)) return std::nullopt;
  auto at = [&](int x, int y) { return costs[static_cast<std::size_t>((y - y0) * w + (x - x0))]; };
  float du = 0.0f, dv = 0.0f;
  const auto finite3 = [](float a, float b, float c) {
    return std::isfinite(a) && std::isfinite(b) && std::isfinite(c);
  };
  if (best_x > x0 && best_x < x1 && finite3(at(best_x - 1, best_y), best, at(best_x + 1, best_y)))
    du = parabola_peak(at(best_x - 1, best_y), best, at(best_x + 1, best_y));
  if (best_y > y0 && best_y < y1 && finite3(at(best_x, best_y - 1), best, at(best_x, best_y + 1)))
    dv = parabola_peak(at(best_x, best_y - 1), best, at(best_x, best_y + 1));
  if (cost != nullptr) *cost = best;
  return std::pair<float, float>{static_cast<float>(best_x) + du, static_cast<float>(best_y) + dv};
}

namespace {

/// The 256 point pairs at half resolution, drawn once: Gaussian (sigma 5 px at half resolution,
/// BRIEF's G II) clipped to the pattern's radius.
struct DescriptorPattern {
  std::array<std::array<std::int8_t, 4>, 256> pairs{};  // x1, y1, x2, y2
  DescriptorPattern() {
    std::uint64_t state = 0x5EED0F0B81EFULL;
    const auto next = [&state] {
      return static_cast<double>(core::splitmix64_next(state) >> 11) * (1.0 / 9007199254740992.0);
    };
    const auto gauss = [&] {
      // Box-Muller from two uniforms in (0, 1].
      const double u1 = 1.0 - next(), u2 = next();
      return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
    };
    constexpr double kSigma = 5.0;
    constexpr int kMax = kDescriptorRadiusPx / 2 - 2;
    for (auto& p : pairs) {
      for (std::int8_t& c : p) {
        const double v = std::clamp(std::round(gauss() * kSigma), -double{kMax}, double{kMax});
        c = static_cast<std::int8_t>(v);
      }
    }
  }
};

const DescriptorPattern& descriptor_pattern() {
  static const DescriptorPattern pattern;
  return pattern;
}

}  // namespace

bool compute_descriptor(const GrayView& half, float u_px, float v_px, Descriptor256& out) {
  const DescriptorPattern& pattern = descriptor_pattern();
  // Level 1 of a 2x2-mean pyramid: full-resolution x maps to (x + 0.5) / 2 - 0.5.
  const int cx = static_cast<int>(std::lround((u_px + 0.5f) * 0.5f - 0.5f));
  const int cy = static_cast<int>(std::lround((v_px + 0.5f) * 0.5f - 0.5f));
  constexpr int kReach = kDescriptorRadiusPx / 2;
  if (cx - kReach < 0 || cy - kReach < 0 || cx + kReach + 1 >= half.width ||
      cy + kReach + 1 >= half.height) {
    return false;
  }
  const auto box = [&](int x, int y) {
    const std::uint8_t* r0 = half.row(cy + y) + cx + x;
    const std::uint8_t* r1 = r0 + half.stride;
    return static_cast<int>(r0[0]) + r0[1] + r1[0] + r1[1];
  };
  out.bits = {};
  for (std::size_t i = 0; i < pattern.pairs.size(); ++i) {
    const auto& p = pattern.pairs[i];
    if (box(p[0], p[1]) < box(p[2], p[3])) out.bits[i / 64] |= std::uint64_t{1} << (i % 64);
  }
  return true;
}

int hamming_distance(const Descriptor256& a, const Descriptor256& b) {
  int d = 0;
  for (std::size_t i = 0; i < 4; ++i) d += std::popcount(a.bits[i] ^ b.bits[i]);
  return d;
}

}  // namespace wallar::dsp
