// SPDX-License-Identifier: Apache-2.0
/// @file test_trajectory_eval.cpp
/// @brief ATE/RPE on hand-computed cases: offsets, rigid copies, known drifts, time matching.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

#include "wallar/dsp/eval/trajectory.hpp"

namespace wallar::dsp {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

StampedPose pose_at(double t_s, const Eigen::Vector3d& p,
                    const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  StampedPose out;
  out.t_ns = std::llround(t_s * 1e9);
  out.T_world_body.linear() = R;
  out.T_world_body.translation() = p;
  return out;
}

// A curved, turning trajectory: 10 s at 10 Hz.
std::vector<StampedPose> curve() {
  std::vector<StampedPose> out;
  for (int k = 0; k <= 100; ++k) {
    const double t = 0.1 * k;
    const Eigen::Vector3d p(std::cos(0.5 * t), 0.7 * std::sin(0.5 * t), 1.5 + 0.1 * std::sin(t));
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(0.3 * std::sin(0.4 * t), Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(0.1 * t, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
    out.push_back(pose_at(t, p, R));
  }
  return out;
}

TEST(TrajectoryEval, ConstantOffsetIsTheAteWithoutAlignmentAndZeroWithIt) {
  const auto gt = curve();
  auto est = gt;
  for (auto& p : est) p.T_world_body.translation() += Eigen::Vector3d(0, 1, 0);  // 1 m in y

  TrajectoryEvalOptions raw;
  raw.align = false;
  const TrajectoryErrors off = evaluate_trajectory(est, gt, raw);
  EXPECT_EQ(off.matched, gt.size());
  EXPECT_NEAR(off.ate_rmse_m, 1.0, 1e-12);
  EXPECT_NEAR(off.ate_max_m, 1.0, 1e-12);
  EXPECT_TRUE(off.T_gt_est.isApprox(SE3d::Identity()));
  // A world-frame offset changes no relative pose.
  EXPECT_NEAR(off.rpe_trans_rmse_m, 0.0, 1e-12);
  EXPECT_NEAR(off.rpe_rot_rmse_deg, 0.0, 1e-6);

  const TrajectoryErrors aligned = evaluate_trajectory(est, gt);
  EXPECT_NEAR(aligned.ate_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(aligned.T_gt_est.translation().y(), -1.0, 1e-9);
}

TEST(TrajectoryEval, RigidCopyAlignsToZero) {
  const auto gt = curve();
  SE3d T_est_gt = SE3d::Identity();  // the estimate's world is rotated and shifted
  T_est_gt.linear() =
      (Eigen::AngleAxisd(70 * kDegToRad, Eigen::Vector3d(1, 2, 3).normalized())).toRotationMatrix();
  T_est_gt.translation() = Eigen::Vector3d(4, -2, 0.5);
  auto est = gt;
  for (auto& p : est) p.T_world_body = T_est_gt * p.T_world_body;

  const TrajectoryErrors e = evaluate_trajectory(est, gt);
  EXPECT_NEAR(e.ate_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(e.ate_max_m, 0.0, 1e-9);
  EXPECT_TRUE(e.T_gt_est.isApprox(T_est_gt.inverse(), 1e-9));
  EXPECT_NEAR(e.rpe_trans_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(e.rpe_rot_rmse_deg, 0.0, 1e-6);

  TrajectoryEvalOptions raw;
  raw.align = false;
  EXPECT_GT(evaluate_trajectory(est, gt, raw).ate_rmse_m, 1.0);
}

TEST(TrajectoryEval, TranslationDriftGivesTheKnownRpe) {
  // gt walks along y at 0.5 m/s for 10 s; the estimate drifts 0.1 m/s along x.
  std::vector<StampedPose> gt, est;
  for (int k = 0; k <= 100; ++k) {
    const double t = 0.1 * k;
    gt.push_back(pose_at(t, {0, 0.5 * t, 1.5}));
    est.push_back(pose_at(t, {0.1 * t, 0.5 * t, 1.5}));
  }
  TrajectoryEvalOptions raw;
  raw.align = false;
  const TrajectoryErrors e = evaluate_trajectory(est, gt, raw);
  EXPECT_NEAR(e.path_length_m, 5.0, 1e-9);
  EXPECT_NEAR(e.rpe_delta_s, 1.0, 1e-9);
  EXPECT_EQ(e.rpe_pairs, 91u);                 // i = 0 .. 9 s, each with j = i + 1 s; none later
  EXPECT_NEAR(e.rpe_trans_rmse_m, 0.1, 1e-9);  // 0.1 m/s over 1 s
  EXPECT_NEAR(e.rpe_rot_rmse_deg, 0.0, 1e-6);
  EXPECT_NEAR(e.ate_max_m, 1.0, 1e-9);  // 0.1 m/s x 10 s
  // RMS of 0.1 t over t = 0, 0.1, .., 10: sqrt(0.01 * mean(t^2)).
  double mean_t2 = 0;
  for (int k = 0; k <= 100; ++k) mean_t2 += 0.01 * k * k / 101.0;
  EXPECT_NEAR(e.ate_rmse_m, std::sqrt(0.01 * mean_t2), 1e-9);

  TrajectoryEvalOptions two_s;
  two_s.rpe_delta_s = 2.0;
  EXPECT_NEAR(evaluate_trajectory(est, gt, two_s).rpe_trans_rmse_m, 0.2, 1e-9);
}

TEST(TrajectoryEval, RotationDriftGivesTheKnownRpe) {
  // Standing still; the estimate's heading drifts 2 deg/s.
  std::vector<StampedPose> gt, est;
  for (int k = 0; k <= 50; ++k) {
    const double t = 0.1 * k;
    gt.push_back(pose_at(t, {1, 2, 1.5}));
    est.push_back(
        pose_at(t, {1, 2, 1.5},
                Eigen::AngleAxisd(2.0 * kDegToRad * t, Eigen::Vector3d::UnitZ()).toRotationMatrix()));
  }
  const TrajectoryErrors e = evaluate_trajectory(est, gt);
  EXPECT_NEAR(e.rpe_rot_rmse_deg, 2.0, 1e-9);
  EXPECT_NEAR(e.rpe_trans_rmse_m, 0.0, 1e-12);
  EXPECT_NEAR(e.path_length_m, 0.0, 1e-12);
}

TEST(TrajectoryEval, InterpolatesGroundTruthAndSkipsUnmatchedTimes) {
  // gt at 10 Hz with a gap from 3 s to 5 s; linear motion and a steady turn.
  auto truth = [](double t) {
    return pose_at(t, {0.3 * t, -0.2 * t, 1.0},
                   Eigen::AngleAxisd(10.0 * kDegToRad * t, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  };
  std::vector<StampedPose> gt;
  for (int k = 0; k <= 100; ++k) {
    if (k > 30 && k < 50) continue;
    gt.push_back(truth(0.1 * k));
  }
  // Estimates at 0.05 s offsets from -1 s to 11 s: exact truth where gt exists.
  std::vector<StampedPose> est;
  std::size_t expected_matches = 0;
  for (int k = -20; k <= 220; ++k) {
    const double t = 0.05 * k;
    est.push_back(truth(t));
    const bool in_gt = t >= -1e-9 && t <= 10.0 + 1e-9 && !(t > 3.0 + 1e-9 && t < 5.0 - 1e-9);
    if (in_gt) ++expected_matches;
  }
  TrajectoryEvalOptions options;
  options.align = false;
  options.max_dt_ns = 60'000'000;  // brackets 0.05 s from each of the two 0.1 s samples
  const TrajectoryErrors e = evaluate_trajectory(est, gt, options);
  EXPECT_EQ(e.matched, expected_matches);
  EXPECT_NEAR(e.ate_rmse_m, 0.0, 1e-9);        // lerp of linear motion is exact
  EXPECT_NEAR(e.rpe_rot_rmse_deg, 0.0, 1e-6);  // slerp of a steady turn is exact
  EXPECT_NEAR(e.rpe_trans_rmse_m, 0.0, 1e-9);
}

TEST(TrajectoryEval, ThrowsOnTooFewMatchesOrUnsortedInput) {
  const auto gt = curve();
  std::vector<StampedPose> est = {pose_at(0.0, {0, 0, 0}), pose_at(0.5, {0, 0, 0}),
                                  pose_at(20.0, {0, 0, 0})};  // the last is after gt ends
  EXPECT_THROW((void)evaluate_trajectory(est, gt), std::invalid_argument);
  EXPECT_THROW((void)evaluate_trajectory(std::vector<StampedPose>{}, gt), std::invalid_argument);
  auto unsorted = gt;
  std::swap(unsorted[3], unsorted[4]);
  EXPECT_THROW((void)evaluate_trajectory(unsorted, gt), std::invalid_argument);
  EXPECT_THROW((void)evaluate_trajectory(gt, unsorted), std::invalid_argument);
  // Estimates between gt samples farther apart than max_dt do not match.
  std::vector<StampedPose> sparse_gt = {pose_at(0, {0, 0, 0}), pose_at(1, {1, 0, 0})};
  std::vector<StampedPose> mid = {pose_at(0.4, {0, 0, 0}), pose_at(0.5, {0, 0, 0}),
                                  pose_at(0.6, {0, 0, 0})};
  EXPECT_THROW((void)evaluate_trajectory(mid, sparse_gt), std::invalid_argument);
}

TEST(TrajectoryEval, AlignRigidRecoversAKnownTransform) {
  std::vector<Eigen::Vector3d> from, to;
  SE3d T = SE3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(-40 * kDegToRad, Eigen::Vector3d(0.2, -1, 0.4).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(-1, 0.5, 2);
  for (int k = 0; k < 7; ++k) {
    from.emplace_back(std::sin(1.3 * k), std::cos(0.7 * k), 0.1 * k * k);
    to.push_back(T * from.back());
  }
  EXPECT_TRUE(align_rigid(from, to).isApprox(T, 1e-9));
  EXPECT_GT(align_rigid(from, to).linear().determinant(), 0.0);
  EXPECT_THROW((void)align_rigid(from, std::span(to).first(6)), std::invalid_argument);
  EXPECT_THROW((void)align_rigid(std::span(from).first(2), std::span(to).first(2)),
               std::invalid_argument);
}

}  // namespace
}  // namespace wallar::dsp
