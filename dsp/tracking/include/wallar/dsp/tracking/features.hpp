// SPDX-License-Identifier: Apache-2.0
/// @file features.hpp
/// @brief The tracker's features on rectified images: segment-test corners with an adaptive
/// threshold, 3x3 non-maximum suppression, bucketing with Shi-Tomasi ranking and a per-bucket
/// cap; stereo matching along rectified rows with sub-pixel refinement and a left-right check.
///
/// Corners: a pixel is a corner when 9 contiguous pixels of the 16 on a radius-3 circle are all
/// brighter than centre + t or all darker than centre - t (the OAST 9-16 criterion that AGAST's
/// decision tree evaluates; here a compass pre-test and a bit-mask run test evaluate it, with the
/// same result). The threshold t adapts frame to frame to keep the corner count near the target.
///
/// Threading: a CornerDetector is used by one thread. Nothing here allocates after construction.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "wallar/dsp/tracking/fixed_vector.hpp"
#include "wallar/dsp/tracking/gray_image.hpp"

namespace wallar::dsp {

struct Corner {
  float u_px = 0.0f, v_px = 0.0f;  //!< rectified left pixel
  float shi_tomasi = 0.0f;         //!< smaller eigenvalue of the 7x7 structure tensor
};

struct DetectorParams {
  int threshold = 20;  //!< starting segment-test threshold [grey levels]
  int threshold_min = 6;
  int threshold_max = 80;
  int target_raw_corners = 2000;  //!< corners before bucketing that the adaptation aims at
  int bucket_px = 48;             //!< bucket side
  int per_bucket = 4;             //!< at most this many features (tracked + new) per bucket
  int border_px = 8;
  float min_shi_tomasi = 20.0f;  //!< weaker corners are dropped
};

class CornerDetector {
 public:
  CornerDetector() = default;
  CornerDetector(int width, int height, const DetectorParams& params);

  [[nodiscard]] int bucket_count() const { return cols_ * rows_; }
  [[nodiscard]] int bucket_of(float u_px, float v_px) const;
  /// Detects corners and keeps, in each bucket, the best (per_bucket - occupancy[bucket]) by
  /// Shi-Tomasi score. `occupancy` has bucket_count() entries (features already tracked).
  /// `out` is cleared first; it is filled until full.
  void detect(const GrayView& image, std::span<const std::uint16_t> occupancy,
              FixedVector<Corner>& out);
  [[nodiscard]] int threshold() const { return threshold_; }
  [[nodiscard]] int last_raw_corners() const { return last_raw_; }

 private:
  DetectorParams params_;
  int width_ = 0, height_ = 0, cols_ = 0, rows_ = 0;
  int threshold_ = 20;
  int last_raw_ = 0;
  std::vector<std::int16_t> score_;      //!< segment-test score per pixel, 0 = no corner
  std::vector<std::uint8_t> candidate_;  //!< one row's pre-filter flags
  std::vector<Corner> bucket_best_;      //!< per_bucket slots per bucket, sorted by score
  std::vector<std::uint8_t> bucket_n_;   //!< filled slots per bucket
};

/// Smaller eigenvalue of the structure tensor over a (2*half+1)^2 window at integer (x, y),
/// with central-difference gradients scaled to grey levels per pixel.
float shi_tomasi_score(const GrayView& image, int x, int y, int half = 3);

struct StereoMatchParams {
  int half_window = 3;            //!< 7x7 patches
  float max_cost_per_px = 12.0f;  //!< zero-mean SAD per pixel
  float uniqueness = 0.9f;        //!< best / second best cost (outside +-1 px) must be below
  float lr_tolerance_px = 1.0f;
  float min_disparity_px = 0.5f;  //!< parallax limit (depth limit at infinity)
  /// Refine the sub-pixel disparity by Gauss-Newton on the shift (the cost parabola locks toward
  /// whole pixels, which biases depths).
  bool subpixel_refine = true;
};

/// Searches the right image's row `v` for the left pixel (u, v) over disparities
/// [d_min, d_max] (whole pixels), checks uniqueness and left-right consistency, and returns the
/// sub-pixel disparity (parabola through the costs), or nothing.
std::optional<float> match_along_row(const GrayView& left, const GrayView& right, float u_px,
                                     float v_px, int d_min, int d_max,
                                     const StereoMatchParams& params);

/// A rectangle of pixels: columns [x0, x1), rows [y0, y1).
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  [[nodiscard]] bool empty() const { return x1 <= x0 || y1 <= y0; }
};

/// The part of the right image (width x height) that match_along_row reads with these
/// arguments, with a margin, clamped to the image: the row search, the left-right check and the
/// sub-pixel refinement. A caller that rectifies the right image on demand makes just this part
/// ready first.
PixelRect match_along_row_reads(int width, int height, float u_px, float v_px, int d_min, int d_max,
                                const StereoMatchParams& params);

/// An 8x8 patch around a pixel, kept with a map point for re-finding it later.
struct Patch8 {
  std::uint8_t px[64] = {};
};
/// Copies the 8x8 patch centred on (u, v) (nearest pixel); false when too close to the border.
bool extract_patch(const GrayView& image, float u_px, float v_px, Patch8& out);
/// Best position of `patch` within +-radius of (u, v) by zero-mean SAD with the window's contrast
/// scaled to the patch's (gain-invariant; windows with under a third or over three times the
/// patch's contrast do not match), refined by parabolas. Returns the mean cost per pixel (grey
/// levels of the patch) through `cost`, or nothing when outside the image, the patch is flat or
/// no window has comparable contrast.
std::optional<std::pair<float, float>> search_patch(const GrayView& image, const Patch8& patch,
                                                    float u_px, float v_px, int radius,
                                                    float* cost);

/// A 256-bit binary descriptor (BRIEF, Calonder et al. 2010): 256 comparisons of smoothed
/// intensities at pairs of points drawn once (seeded, isotropic Gaussian around the feature).
/// Used to find map points again by appearance (relocalisation), where no pose is known.
struct Descriptor256 {
  std::array<std::uint64_t, 4> bits{};
};
/// The descriptor of the feature at full-resolution (u, v), sampled on `half`, an image at half
/// resolution (a pyramid's level 1: its 2x2 means are the smoothing); each test compares 2x2
/// means there. False when the pattern leaves the image.
bool compute_descriptor(const GrayView& half, float u_px, float v_px, Descriptor256& out);
/// Bits that differ.
int hamming_distance(const Descriptor256& a, const Descriptor256& b);
/// The pattern's reach from the feature at full resolution [px] (for border checks).
inline constexpr int kDescriptorRadiusPx = 28;

}  // namespace wallar::dsp
