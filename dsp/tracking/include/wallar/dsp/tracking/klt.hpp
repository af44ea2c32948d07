// SPDX-License-Identifier: Apache-2.0
/// @file klt.hpp
/// @brief Pyramidal Lucas-Kanade optical flow of single points between two pyramids
/// (Bouguet's formulation: translation only, coarse to fine, template from the previous image),
/// with the frames' brightness relation (an auto-exposure or gain step: cur = gain * prev + bias)
/// applied to every window. One global relation rather than two unknowns per window: those
/// would loosen the alignment of every track to absorb a change that is the same for all.
///
/// Threading: free functions, no state; nothing allocates (windows live on the stack).
#pragma once

#include <span>

#include "wallar/dsp/tracking/gray_image.hpp"

namespace wallar::dsp {

struct KltParams {
  int half_window = 5;         //!< 11x11 windows
  int max_iterations = 15;     //!< per level
  float epsilon_px = 0.02f;    //!< stop when the update is smaller
  float max_mean_abs = 25.0f;  //!< mean |residual| at level 0 above this: lost
  float min_eigen = 1e-3f;     //!< smaller eigenvalue of the normalised gradient matrix
};

/// cur ~ gain * prev + bias, frame-wide.
struct Brightness {
  float gain = 1.0f, bias = 0.0f;
};
/// The frame-wide brightness relation from intensities sampled at corresponding places of the
/// two frames (the tracks' last positions and their predicted ones, on a coarse level): medians
/// and median deviations, robust to mispredicted samples. Gains within 1 +- min_change and
/// offsets under 255 * min_change are taken as no change (the scene's own variation). Reorders
/// the samples.
Brightness estimate_brightness(std::span<float> prev_samples, std::span<float> cur_samples,
                               float min_change = 0.15f);

/// Tracks the point at (u0, v0) in `prev` into `cur`. (u, v) is the initial guess in `cur` on
/// input (e.g. the map point's predicted projection) and the result on output. Returns false
/// when the point left the image, the gradient matrix is singular, or the match is poor.
bool klt_track(const Pyramid& prev, const Pyramid& cur, float u0, float v0, float& u, float& v,
               const KltParams& params = {}, const Brightness& brightness = {});

}  // namespace wallar::dsp
