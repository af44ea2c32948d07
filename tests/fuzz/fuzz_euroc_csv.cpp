// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_euroc_csv.cpp
/// @brief Fuzzes the EuRoC CSV readers (camera, IMU, ground truth) with the same input.
#include <string>

#include "fuzz_common.hpp"
#include "wallar/drivers/recording/euroc.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wallar;
  const std::string_view text = fuzz::as_text(data, size);
  const std::string name = "fuzz.csv";
  fuzz::expect_only_input_errors([&] {
    const auto frames = recording::parse_camera_csv(text, name);
    for (std::size_t i = 1; i < frames.size(); ++i) {
      if (frames[i].t_ns <= frames[i - 1].t_ns || frames[i].filename.empty()) __builtin_trap();
    }
  });
  fuzz::expect_only_input_errors([&] {
    const auto imu = recording::parse_imu_csv(text, name);
    for (std::size_t i = 1; i < imu.size(); ++i) {
      if (imu[i].t_ns <= imu[i - 1].t_ns) __builtin_trap();
    }
  });
  fuzz::expect_only_input_errors([&] {
    const auto gt = recording::parse_ground_truth_csv(text, name);
    for (const auto& g : gt) {
      if (!g.T_world_body.matrix().allFinite()) __builtin_trap();
    }
  });
  return 0;
}
