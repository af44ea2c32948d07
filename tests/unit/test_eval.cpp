// SPDX-License-Identifier: Apache-2.0
/// @file test_eval.cpp
/// @brief The evaluation suite (issue 4): the scene generator's counts and labels, eq. 3.6 and
/// eq. 3.7 against hand-computed values, the sweeps' argument checks, and a small sweep showing
/// the thesis's central claim: plain RANSAC fails on the §4.1 scene, BSF and B-RANSAC succeed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "wallar/core/error.hpp"
#include "wallar/dsp/eval/metrics.hpp"
#include "wallar/dsp/walls/synthetic.hpp"
#include "wallar/eval/experiments.hpp"

namespace wallar {
namespace {

std::size_t count(const dsp::LabelledCloud& c, dsp::PointLabel l) {
  return static_cast<std::size_t>(std::count(c.labels.begin(), c.labels.end(), l));
}

TEST(ThesisScene, CountsAndLabelsMatchTheParameters) {
  dsp::ThesisSceneParams p;
  p.wall_points = 120;
  p.plane_points = 170;
  p.outliers = 60;
  p.rho_b = 0.4;  // N_back = 0.4 / 0.6 * 120 = 80
  p.window_points = 33;
  p.clutter_points = 41;
  p.clutter_objects = 3;
  p.seed = 7;
  const auto s = dsp::make_thesis_scene(p);
  ASSERT_EQ(s.cloud.size(), s.labels.size());
  EXPECT_EQ(s.cloud.size(), 120u + 170u + 80u + 60u + 33u + 41u);
  EXPECT_EQ(count(s, dsp::PointLabel::kWall), 120u);
  EXPECT_EQ(count(s, dsp::PointLabel::kFrontPlane), 170u);
  EXPECT_EQ(count(s, dsp::PointLabel::kBacklier), 80u);
  EXPECT_EQ(count(s, dsp::PointLabel::kOutlier), 60u);
  EXPECT_EQ(count(s, dsp::PointLabel::kWindow), 33u);
  EXPECT_EQ(count(s, dsp::PointLabel::kClutter), 41u);
  const double half = p.noise_m / 2 + 1e-6;
  for (std::size_t i = 0; i < s.cloud.size(); ++i) {
    const Eigen::Vector3d q = s.cloud.point(i).cast<double>();
    const double dist = s.wall.signed_distance(q);  // > 0 in front of the wall
    switch (s.labels[i]) {
      case dsp::PointLabel::kWall:
        EXPECT_LE(std::abs(dist), half);
        EXPECT_LE(std::abs(q.x()), p.wall_size_m / 2);
        break;
      case dsp::PointLabel::kFrontPlane:
        EXPECT_NEAR(q.z(), p.plane_distance_m, half);
        EXPECT_LE(std::abs(q.x()), p.plane_size_m / 2);
        break;
      case dsp::PointLabel::kBacklier:
      case dsp::PointLabel::kWindow:
        EXPECT_LT(dist, -p.noise_m / 2 + 1e-6) << "behind the wall";
        break;
      case dsp::PointLabel::kOutlier:
      case dsp::PointLabel::kClutter:
        EXPECT_GT(dist, 0.0) << "in front of the wall";
        break;
      default:
        ADD_FAILURE() << "unexpected label";
    }
  }
  // The wall's ground truth faces the viewpoint at the origin.
  EXPECT_GT(s.wall.signed_distance(Eigen::Vector3d::Zero()), 0.0);
  // Windows and clutter are drawn last: the rest of the seed's scene is unchanged.
  p.window_points = 0;
  p.clutter_points = 0;
  const auto plain = dsp::make_thesis_scene(p);
  ASSERT_EQ(plain.cloud.size(), 430u);
  for (std::size_t i = 0; i < plain.cloud.size(); ++i) {
    ASSERT_EQ(plain.cloud.point(i), s.cloud.point(i)) << i;
  }
}

TEST(Metrics, Eq36ProjectsOntoTheEstimateBeforeMeasuring) {
  const Plane truth{-Eigen::Vector3d::UnitZ(), -2.0};  // z = 2, facing the origin
  // Estimate parallel to the truth, 3 cm nearer: z = 1.97. Inliers scattered around it; their
  // scatter across the estimate must not count, only the estimate's offset: RMSE = 0.03.
  const Plane estimate{-Eigen::Vector3d::UnitZ(), -1.97};
  const std::vector<Eigen::Vector3d> inliers = {
      {0, 0, 1.90}, {1, 0, 2.05}, {0, 1, 1.97}, {-1, -1, 2.00}};
  EXPECT_NEAR(dsp::projected_inlier_rmse(inliers, estimate, truth), 0.03, 1e-12);
  // A tilted estimate through (0, 0, 2): the projected points lie at z = 2 + 0.1 x. Their
  // distances to the truth are 0.1 x for x = 0, 1, -1 -> RMSE = sqrt((0 + 0.01 + 0.01) / 3).
  const Eigen::Vector3d n = Eigen::Vector3d(0.1, 0, -1).normalized();
  const Plane tilted{n, n.dot(Eigen::Vector3d(0, 0, 2))};
  const std::vector<Eigen::Vector3d> on_tilted = {{0, 0, 2.0}, {1, 0, 2.1}, {-1, 0, 1.9}};
  EXPECT_NEAR(dsp::projected_inlier_rmse(on_tilted, tilted, truth), std::sqrt(0.02 / 3), 1e-12);
  EXPECT_EQ(dsp::projected_inlier_rmse({}, tilted, truth), 0.0);

  const dsp::PlaneError e = dsp::plane_error(tilted, truth);
  EXPECT_NEAR(e.angle_deg, std::atan(0.1) * 180 / M_PI, 1e-9);
  EXPECT_NEAR(e.offset_m, 0.0, 1e-12);  // passes through the truth's foot point (0, 0, 2)
  // Either sign of the normal is the same plane.
  EXPECT_NEAR(dsp::plane_error(estimate.flipped(), truth).angle_deg, 0.0, 1e-9);
  EXPECT_NEAR(dsp::plane_error(estimate.flipped(), truth).offset_m, 0.03, 1e-12);
}

TEST(Metrics, Eq37RobustnessAndTheSuccessCriterion) {
  dsp::Robustness r;
  EXPECT_EQ(r.value(), 0.0);
  for (bool ok : {true, false, true, true, false, false, false, true}) r.add(ok);
  EXPECT_EQ(r.trials, 8u);
  EXPECT_EQ(r.successes, 4u);
  EXPECT_DOUBLE_EQ(r.value(), 0.5);
  const dsp::SuccessCriterion c{5.0, 0.1};
  EXPECT_TRUE(c.success({4.9, 0.09}));
  EXPECT_FALSE(c.success({5.1, 0.0}));
  EXPECT_FALSE(c.success({0.0, 0.11}));
  EXPECT_EQ(c.describe(), "normal within 5 deg and offset within 0.1 m of the true wall");
}

TEST(SweepArguments, BadInputIsRejectedWithTheFlagNamed) {
  EXPECT_EQ(eval::parse_range("0:1:0.25", "beta"), (std::vector<double>{0, 0.25, 0.5, 0.75, 1}));
  EXPECT_EQ(eval::parse_range("0:0.3:0.1", "beta").back(), 0.3);  // not lost to rounding
  EXPECT_EQ(eval::parse_range("0.5, 2", "beta"), (std::vector<double>{0.5, 2}));
  EXPECT_EQ(eval::parse_seeds("3-5"), (std::vector<std::uint64_t>{3, 4, 5}));
  EXPECT_EQ(eval::parse_seeds("9,1"), (std::vector<std::uint64_t>{9, 1}));
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message([] { eval::parse_range("1:0:0.1", "beta"); }),
            "--beta: empty range: HI < LO in '1:0:0.1'");
  EXPECT_EQ(message([] { eval::parse_range("0:1:0", "rho-b"); }),
            "--rho-b: step must be > 0, got '0:1:0'");
  EXPECT_EQ(message([] { eval::parse_range("0,x", "rho"); }), "--rho: 'x' is not a number");
  EXPECT_EQ(message([] { eval::parse_range("", "rho"); }), "--rho: '' is not a number");
  EXPECT_EQ(message([] { eval::parse_seeds("1,two"); }),
            "--seeds: 'two' is not an unsigned integer");
  EXPECT_EQ(message([] { eval::parse_seeds("5-2"); }), "--seeds: empty range '5-2'");
  EXPECT_EQ(message([] { eval::parse_method("lmeds"); }),
            "--methods: unknown method 'lmeds' (known: ransac, msac, bsf, binomial, pcl, open3d)");
  eval::SweepOptions o;
  o.grids["beta"] = {0.5};
  EXPECT_EQ(message([&] { eval::check_sweep("threshold", o); }),
            "--beta: does not apply to sweep 'threshold' (it takes --threshold-m)");
  EXPECT_NE(message([] { eval::check_sweep("nope", {}); }).find("unknown sweep 'nope'"),
            std::string::npos);
}

// The thesis's claim on its own scene (§4.1, threshold 0.1 m, beta 0.5, rho set near rho_b):
// the plane in front has more points than the wall, so RANSAC finds it; BSF and B-RANSAC find
// the wall.
TEST(ThesisClaim, RansacFailsWhereBsfAndBinomialSucceed) {
  const dsp::SuccessCriterion criterion;
  for (double rho_b : {0.1, 0.3, 0.5}) {
    dsp::Robustness ransac, msac, bsf, binomial;
    for (std::uint64_t seed = 1; seed <= 5; ++seed) {
      dsp::ThesisSceneParams p;
      p.rho_b = rho_b;
      p.seed = seed;
      const auto scene = dsp::make_thesis_scene(p);
      eval::TrialSetup s;
      s.seed = seed;
      s.threshold_m = 0.1;
      s.method = eval::Method::kRansac;
      const auto r = eval::run_trial(scene, s, criterion);
      ransac.add(r.success);
      ASSERT_TRUE(r.found);
      EXPECT_LT(r.error.offset_m + 1e-9, 1.1);
      EXPECT_NEAR(r.plane.d, -1.0, 0.1) << "RANSAC takes the bigger plane in front";
      s.method = eval::Method::kMsac;
      msac.add(eval::run_trial(scene, s, criterion).success);
      s.method = eval::Method::kBsf;
      s.beta = 0.5;
      const auto b = eval::run_trial(scene, s, criterion);
      bsf.add(b.success);
      EXPECT_LT(b.rmse_m, 0.02) << "eq. 3.6 of the wall found by BSF";
      s.method = eval::Method::kBinomial;
      s.rho = rho_b + 0.05;
      binomial.add(eval::run_trial(scene, s, criterion).success);
    }
    EXPECT_EQ(ransac.value(), 0.0) << "rho_b " << rho_b;
    EXPECT_EQ(msac.value(), 0.0) << "rho_b " << rho_b;
    EXPECT_EQ(bsf.value(), 1.0) << "rho_b " << rho_b;
    EXPECT_EQ(binomial.value(), 1.0) << "rho_b " << rho_b;
  }
}

TEST(Sweeps, SmallBsfSweepWritesItsTableAndShowsTheBand) {
  const auto dir = std::filesystem::temp_directory_path() / "wallar_test_eval_sweep";
  std::filesystem::remove_all(dir);
  eval::OutputDir out(dir, false);  // no gnuplot needed for the test
  eval::SweepOptions o;
  o.seeds = {1, 2, 3};
  o.grids["beta"] = {0.0, 0.5, 5.0};
  o.grids["rho-b"] = {0.2};
  const auto j = eval::run_sweep("bsf", o, out);
  EXPECT_EQ(j["trials"], 9);
  std::ifstream csv(dir / "bsf.csv");
  std::stringstream ss;
  ss << csv.rdbuf();
  std::vector<std::string> rows;
  for (std::string line; std::getline(ss, line);) rows.push_back(line);
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0], "beta,rho_b,successes,trials,robustness,mean_rmse_m");
  // beta 0 is RANSAC (fails); 0.5 works; 5 lets the backliers outweigh the wall (fails).
  EXPECT_EQ(rows[1].rfind("0,0.2,0,3,0,", 0), 0u) << rows[1];
  EXPECT_EQ(rows[2].rfind("0.5,0.2,3,3,1,", 0), 0u) << rows[2];
  EXPECT_EQ(rows[3].rfind("5,0.2,0,3,0,", 0), 0u) << rows[3];
  EXPECT_TRUE(std::filesystem::exists(dir / "bsf.gp"));
  EXPECT_FALSE(std::filesystem::exists(dir / "bsf.csv.part"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace wallar
