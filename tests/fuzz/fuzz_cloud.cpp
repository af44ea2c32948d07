// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_cloud.cpp
/// @brief Fuzzes the point-cloud readers (PLY, PCD incl. LZF binary_compressed, CSV/XYZ) with
/// the same input; every parsed cloud must be internally consistent and hold finite points.
#include <cmath>
#include <string>

#include "fuzz_common.hpp"
#include "wallar/drivers/cloud/cloud_io.hpp"

namespace {

void check(const wallar::PointCloud& c) {
  if (!c.consistent()) __builtin_trap();
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (!std::isfinite(c.x[i]) || !std::isfinite(c.y[i]) || !std::isfinite(c.z[i])) {
      __builtin_trap();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wallar;
  const std::string_view bytes = fuzz::as_text(data, size);
  const std::string name = "fuzz.cloud";
  fuzz::expect_only_input_errors([&] {
    cloud::CloudReadStats stats;
    const PointCloud c = cloud::parse_ply(bytes, name, &stats);
    check(c);
    if (stats.points_read != c.size()) __builtin_trap();
  });
  fuzz::expect_only_input_errors([&] {
    cloud::CloudReadStats stats;
    const PointCloud c = cloud::parse_pcd(bytes, name, &stats);
    check(c);
    if (stats.points_read != c.size()) __builtin_trap();
  });
  fuzz::expect_only_input_errors([&] { check(cloud::parse_xyz_csv(bytes, name, nullptr)); });
  return 0;
}
