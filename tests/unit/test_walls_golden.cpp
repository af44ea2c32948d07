// SPDX-License-Identifier: Apache-2.0
/// @file test_walls_golden.cpp
/// @brief Cross-architecture check: detections on fixed scenes and seeds must reproduce the
/// committed results (tests/data/golden/walls.json, made on x86-64) on every SIMD path,
/// including NEON under qemu-aarch64. Set WALLAR_UPDATE_GOLDEN=1 to rewrite the file after an
/// intended change (and say why in the commit).
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "simd_targets.hpp"
#include "wallar/dsp/walls/plane_kernel.hpp"
#include "wallar/dsp/walls/synthetic.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"

namespace wallar::dsp {
namespace {

nlohmann::json detections() {
  nlohmann::json out = nlohmann::json::array();
  const auto record = [&](const std::string& name, const Detection& d) {
    out.push_back({{"case", name},
                   {"n", {d.plane.n.x(), d.plane.n.y(), d.plane.n.z()}},
                   {"d", d.plane.d},
                   {"inliers", d.inliers},
                   {"backliers", d.backliers},
                   {"rounds", d.rounds}});
  };
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    ThesisSceneParams p;
    p.seed = seed;
    const auto scene = make_thesis_scene(p);
    for (ScoreMethod m : {ScoreMethod::kRansac, ScoreMethod::kBsf, ScoreMethod::kBinomial,
                          ScoreMethod::kContrast}) {
      DetectorConfig cfg;
      cfg.method = m;
      cfg.threshold_m = 0.1;
      cfg.seed = seed;
      WallDetector det(scene.cloud.size(), cfg);
      det.set_points(scene.cloud);
      record("thesis/" + std::to_string(seed) + "/" + std::to_string(static_cast<int>(m)),
             det.detect_3d());
    }
    SparseMapParams sp;
    sp.seed = seed;
    const auto map = make_sparse_map(sp);
    DetectorConfig cfg;
    cfg.threshold_m = 0.03;
    cfg.seed = seed;
    WallDetector det(map.cloud.size(), cfg);
    det.set_points(map.cloud);
    record("map3d/" + std::to_string(seed), det.detect_3d());
    det.set_points(map.cloud, Eigen::Vector3d(0.0, 9.81, 0.0));
    record("map2d/" + std::to_string(seed), det.detect_vertical());
  }
  return out;
}

void compare(const nlohmann::json& golden, const nlohmann::json& now);

TEST(GoldenWalls, SameDetectionsOnEveryArchitecture) {
  const std::string path = std::string(WALLAR_TEST_DATA) + "/golden/walls.json";
  const nlohmann::json now = detections();
  if (std::getenv("WALLAR_UPDATE_GOLDEN") != nullptr) {
    std::ofstream(path) << now.dump(1) << "\n";
    GTEST_FAIL() << "rewrote " << path << " (unset WALLAR_UPDATE_GOLDEN)";
  }
  std::ifstream in(path);
  ASSERT_TRUE(in) << path;
  const nlohmann::json golden = nlohmann::json::parse(in);
  compare(golden, now);
}

// Every SIMD target compiled in and supported by this CPU gives the same detections.
TEST(GoldenWalls, EverySimdTargetOfThisMachineAgrees) {
  const std::string path = std::string(WALLAR_TEST_DATA) + "/golden/walls.json";
  std::ifstream in(path);
  ASSERT_TRUE(in) << path;
  const nlohmann::json golden = nlohmann::json::parse(in);
  const std::size_t ran = test::for_each_simd_target([&] { compare(golden, detections()); });
  EXPECT_GE(ran, 1u) << test::simd_filter();
}

void compare(const nlohmann::json& golden, const nlohmann::json& now) {
  ASSERT_EQ(golden.size(), now.size());
  for (std::size_t i = 0; i < now.size(); ++i) {
    const auto& g = golden[i];
    const auto& c = now[i];
    SCOPED_TRACE(g["case"].get<std::string>() + " on " + plane_kernel_target());
    EXPECT_EQ(c["inliers"], g["inliers"]);
    EXPECT_EQ(c["backliers"], g["backliers"]);
    EXPECT_EQ(c["rounds"], g["rounds"]);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(c["n"][k].get<double>(), g["n"][k].get<double>(), 1e-5);
    EXPECT_NEAR(c["d"].get<double>(), g["d"].get<double>(), 1e-5);
  }
}

}  // namespace
}  // namespace wallar::dsp
