// SPDX-License-Identifier: Apache-2.0
/// @file v4l2_modes.hpp
/// @brief What a V4L2 capture device offers (VIDIOC_ENUM_FMT, _ENUM_FRAMESIZES,
/// _ENUM_FRAMEINTERVALS), and whether a board's mode is among it: `wallar run --check` asks
/// each camera before anything streams, so a camera that cannot give the calibrated mode is
/// one line naming the board key, not a refusal at start or a rate nobody asked for.
///
/// Threading: plain functions on the calling thread (they open and close the device).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "wallar/drivers/camera/v4l2_system.hpp"

namespace wallar::drivers {

/// One frame size of one pixel format, with its frame rates.
struct V4l2Mode {
  std::uint32_t fourcc = 0;
  int width_px = 0;
  int height_px = 0;
  /// Discrete rates [Hz], fastest first; for a stepwise or continuous range, its ends.
  std::vector<double> fps;
  bool fps_range = false;   //!< fps holds [min, max] of a continuous or stepwise range
  bool size_range = false;  //!< a stepwise size range: width/height its largest
  int min_width_px = 0, min_height_px = 0;
};

/// The device's capture modes. Throws DeviceError "PATH: cannot open: STRERROR" when it cannot
/// be opened; a device that answers no enumeration gives an empty list.
std::vector<V4l2Mode> enumerate_v4l2_modes(V4l2System& sys, const std::string& path);

/// Whether the device offers `fourcc` at width x height; with fps > 0, at that rate too
/// (within 1 %).
bool offers_mode(const std::vector<V4l2Mode>& modes, std::uint32_t fourcc, int width_px,
                 int height_px, double fps = 0.0);

/// "YUYV 640x480 @ 30/15 Hz, MJPG 1280x720 @ 30 Hz" (at most `max` modes, then "...").
std::string describe_modes(const std::vector<V4l2Mode>& modes, std::size_t max = 8);

}  // namespace wallar::drivers
