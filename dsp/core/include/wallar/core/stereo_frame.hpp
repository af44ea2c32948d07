// SPDX-License-Identifier: Apache-2.0
/// @file stereo_frame.hpp
/// @brief A left/right image pair taken together; images are counted references.
///
/// Threading: a value type; copying shares the pixel buffers (no pixel copies).
#pragma once

#include <cstdint>

#include "wallar/core/image.hpp"
#include "wallar/core/time.hpp"

namespace wallar {

/// One camera image with its timing.
struct CameraFrame {
  TimeNs t_ns = 0;             //!< exposure time stamp [ns]
  TimeNs publish_t_ns = 0;     //!< when the driver/replay handed it on [ns], 0 = unknown
  std::uint64_t sequence = 0;  //!< driver or recording sequence number
  Image image;
};

/// A synchronised stereo pair; t_ns is the left image's time.
struct StereoFrame {
  TimeNs t_ns = 0;             //!< left exposure time [ns]
  std::uint64_t sequence = 0;  //!< pair number, counting from 0
  CameraFrame left;
  CameraFrame right;

  /// Right minus left exposure time [ns].
  [[nodiscard]] DurationNs skew_ns() const { return right.t_ns - left.t_ns; }
};

}  // namespace wallar
