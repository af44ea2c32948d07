// SPDX-License-Identifier: Apache-2.0
/// @file klt.hpp
/// @brief Pyramidal Lucas-Kanade optical flow of single points between two pyramids
/// (Bouguet's formulation: translation only, coarse to fine, template from the previous image).
///
/// Threading: free functions, no state; nothing allocates (windows live on the stack).
#pragma once

#include "wallar/dsp/tracking/gray_image.hpp"

namespace wallar::dsp {

struct KltParams {
  int half_window = 5;        //!< 11x11 windows
  int max_iterations = 15;    //!< per level
  float epsilon_px = 0.02f;   //!< stop when the update is smaller
  float max_mean_abs = 25.0f; //!< mean |residual| at level 0 above this: lost
  float min_eigen = 1e-3f;    //!< smaller eigenvalue of the normalised gradient matrix
};

/// Tracks the point at (u0, v0) in `prev` into `cur`. (u, v) is the initial guess in `cur` on
/// input (e.g. the map point's predicted projection) and the result on output. Returns false
/// when the point left the image, the gradient matrix is singular, or the match is poor.
bool klt_track(const Pyramid& prev, const Pyramid& cur, float u0, float v0, float& u, float& v,
               const KltParams& params = {});

}  // namespace wallar::dsp
