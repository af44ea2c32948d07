// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_sensor_yaml.cpp
/// @brief Fuzzes the EuRoC camera sensor.yaml reader (OpenCV-flavoured YAML, T_BS checks).
#include <cmath>
#include <string>

#include "fuzz_common.hpp"
#include "wallar/drivers/recording/euroc.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  wallar::fuzz::expect_only_input_errors([&] {
    const wallar::CameraCalibration c = wallar::recording::parse_camera_sensor_yaml(
        wallar::fuzz::as_text(data, size), "sensor.yaml");
    // What the reader promises about an accepted file.
    if (c.width_px <= 0 || c.height_px <= 0 || !(c.fx > 0.0) || !(c.fy > 0.0) ||
        !(c.rate_hz > 0.0) || c.distortion.size() != 4 || !c.T_body_cam.matrix().allFinite()) {
      __builtin_trap();
    }
  });
  return 0;
}
