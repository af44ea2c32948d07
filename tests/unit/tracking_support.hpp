// SPDX-License-Identifier: Apache-2.0
/// @file tracking_support.hpp
/// @brief Helpers shared by the tracker's tests.
///
/// Threading: test-thread only.
#pragma once

#include <cstdint>

#include "wallar/core/image.hpp"
#include "wallar/dsp/tracking/gray_image.hpp"
#include "wallar/dsp/tracking/synthetic_room.hpp"

namespace wallar::test {

/// The tracker's view of a gray image (no copy: `img` must outlive it).
inline dsp::GrayView gray_view(const Image& img) {
  return {img.data(), img.width(), img.height(), img.stride_bytes()};
}

/// A room small enough that its walls are 2-3 m from the path (EuRoC-like rig).
inline dsp::SyntheticRoom small_room(std::uint64_t texture_seed = 1) {
  dsp::SyntheticRoom room;
  room.x_min_m = -2.0;
  room.x_max_m = 2.0;
  room.y_min_m = -2.5;
  room.y_max_m = 2.5;
  room.z_max_m = 2.5;
  room.texture_seed = texture_seed;
  return room;
}

}  // namespace wallar::test
