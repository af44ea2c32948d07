// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_calibration.cpp
/// @brief Fuzzes the stereo calibration reader (Kalibr camchain and OpenCV stereo YAML).
#include <string>

#include "fuzz_common.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  wallar::fuzz::expect_only_input_errors([&] {
    const wallar::RigCalibration rig = wallar::recording::parse_rig_calibration(
        wallar::fuzz::as_text(data, size), "calibration.yaml");
    // What the reader promises about an accepted file.
    for (const wallar::CameraCalibration& c : rig.cams) {
      if (c.width_px < 1 || c.width_px > 16384 || c.height_px < 1 || c.height_px > 16384 ||
          !(c.fx > 0.0) || !(c.fy > 0.0) || c.distortion.size() < 4 || c.distortion.size() > 5 ||
          !c.T_body_cam.matrix().allFinite()) {
        __builtin_trap();
      }
    }
  });
  return 0;
}
