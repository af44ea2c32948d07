// SPDX-License-Identifier: Apache-2.0
/// @file tracking_support.hpp
/// @brief Helpers shared by the tracker's tests.
///
/// Threading: test-thread only.
#pragma once

#include "wallar/core/image.hpp"
#include "wallar/dsp/tracking/gray_image.hpp"

namespace wallar::test {

/// The tracker's view of a gray image (no copy: `img` must outlive it).
inline dsp::GrayView gray_view(const Image& img) {
  return {img.data(), img.width(), img.height(), img.stride_bytes()};
}

}  // namespace wallar::test
