// SPDX-License-Identifier: Apache-2.0
/// @file test_tum_trajectory.cpp
/// @brief TUM trajectory text: lossless round trip, comments, file:line errors.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/tum_trajectory.hpp"

namespace wallar::recording {
namespace {

std::vector<StampedPose> sample_poses() {
  std::vector<StampedPose> out;
  for (int k = 0; k < 20; ++k) {
    StampedPose p;
    p.t_ns = 1'700'000'000'123'456'789 + k * 50'000'001LL;  // epoch-sized: needs all 19 digits
    const double a = 0.37 * k;
    p.T_world_body = make_se3(Eigen::Quaterniond(Eigen::AngleAxisd(
                                  a, Eigen::Vector3d(std::sin(a), 1.0, 0.3).normalized())),
                              Eigen::Vector3d(0.1 * k, -2.5 + 0.01 * k, 1.23456789));
    out.push_back(p);
  }
  return out;
}

TEST(TumTrajectory, RoundTripIsExactInTimeAndTightInPose) {
  const auto poses = sample_poses();
  const std::string text = format_tum(poses);
  const auto back = parse_tum(text, "traj.txt");
  ASSERT_EQ(back.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(back[i].t_ns, poses[i].t_ns);
    EXPECT_TRUE(back[i].T_world_body.isApprox(poses[i].T_world_body, 1e-8)) << i;
  }
  EXPECT_EQ(format_tum(back), text);  // a second round trip is byte-identical
}

TEST(TumTrajectory, FormatsTheDocumentedLine) {
  StampedPose p;
  p.t_ns = 1'500'000'000;
  // A rotation whose quaternion Eigen may give with w < 0: written with qw >= 0.
  p.T_world_body = make_se3(Eigen::Quaterniond(-0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(1, 2.5, -3));
  EXPECT_EQ(format_tum(std::vector<StampedPose>{p}), "1.500000000 1 2.5 -3 -0.5 0.5 -0.5 0.5\n");
  p.t_ns = -250'000'000;
  p.T_world_body = SE3d::Identity();
  EXPECT_EQ(format_tum(std::vector<StampedPose>{p}), "-0.250000000 0 0 0 0 0 0 1\n");
}

TEST(TumTrajectory, SkipsCommentsAndBlankLines) {
  const std::string text =
      "# timestamp tx ty tz qx qy qz qw\n"
      "\n"
      "1.5 0 0 0 0 0 0 1\r\n"
      "   # indented comment\n"
      "\t2.25\t1 2 3  0 0 0.7071067811865476 0.7071067811865476\n"
      "1305031102.1753040115 0 0 0 0 0 0 1";  // 10 decimals: rounded; no final newline
  const auto poses = parse_tum(text, "t.txt");
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_EQ(poses[0].t_ns, 1'500'000'000);
  EXPECT_EQ(poses[1].t_ns, 2'250'000'000);
  EXPECT_EQ(poses[2].t_ns, 1'305'031'102'175'304'012);
  EXPECT_TRUE(poses[1].T_world_body.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  EXPECT_TRUE(poses[1].T_world_body.linear().isApprox(
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-12));
  EXPECT_EQ(parse_tum("1e-3 0 0 0 0 0 0 1\n", "x")[0].t_ns, 1'000'000);
}

std::string error_of(const std::string& text) {
  try {
    (void)parse_tum(text, "run/traj.txt");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(TumTrajectory, BadLinesNameSourceAndLine) {
  const std::string head = "# header\n0.1 0 0 0 0 0 0 1\n";
  EXPECT_EQ(error_of(head + "0.2 0 0 0 0 0 1\n"),
            "run/traj.txt:3: expected 8 fields 't x y z qx qy qz qw', got 7");
  EXPECT_EQ(error_of(head + "0.2 0 0 0 0 0 0 1 9\n"),
            "run/traj.txt:3: expected 8 fields 't x y z qx qy qz qw', got 9");
  EXPECT_EQ(error_of(head + "0.2 0 zero 0 0 0 0 1\n"),
            "run/traj.txt:3: y must be a finite number, got 'zero'");
  EXPECT_EQ(error_of(head + "0.2 0 0 nan 0 0 0 1\n"),
            "run/traj.txt:3: z must be a finite number, got 'nan'");
  EXPECT_EQ(error_of(head + "abc 0 0 0 0 0 0 1\n"),
            "run/traj.txt:3: time must be a number of seconds, got 'abc'");
  EXPECT_EQ(error_of(head + "0.2 0 0 0 0 0 0 2\n"),
            "run/traj.txt:3: quaternion norm 2.000000 is not 1");
  EXPECT_EQ(error_of(head + "\n0.1 0 0 0 0 0 0 1\n"),
            "run/traj.txt:4: time 0.1 s is not after the previous line's");
  EXPECT_TRUE(parse_tum("", "empty").empty());
}

}  // namespace
}  // namespace wallar::recording
