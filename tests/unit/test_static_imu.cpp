// SPDX-License-Identifier: Apache-2.0
/// @file test_static_imu.cpp
/// @brief Gravity and gyro bias at rest, on synthetic samples and on the real recording.
#include <gtest/gtest.h>

#include <random>

#include "test_support.hpp"
#include "wallar/dsp/imu/static_init.hpp"

namespace wallar::test {
namespace {

TEST(StaticImu, RecoversATiltedGravityAndTheGyroBias) {
  std::mt19937 rng(42);
  std::normal_distribution<double> n(0.0, 0.05);
  const Eigen::Vector3d up_body = Eigen::Vector3d(0.3, -0.2, 0.93).normalized();
  const Eigen::Vector3d bias(0.01, -0.02, 0.005);
  std::vector<ImuSample> samples;
  for (int i = 0; i < 2000; ++i) {
    ImuSample s;
    s.t_ns = i * 5 * kNsPerMs;
    s.accel_m_s2 = 9.81 * up_body + Eigen::Vector3d(n(rng), n(rng), n(rng));
    s.gyro_rad_s = bias + 0.1 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    samples.push_back(s);
  }
  const auto est = dsp::estimate_static_imu(samples, 0, 10 * kNsPerS);
  ASSERT_TRUE(est);
  EXPECT_EQ(est->samples, 2000u);
  EXPECT_LT((est->gyro_bias_rad_s - bias).norm(), 1e-3);
  EXPECT_LT(std::acos(est->mean_accel_m_s2.normalized().dot(up_body)), 1e-3);
  EXPECT_TRUE(dsp::is_still(*est));
  // The rotation takes the body's "up" to world z.
  EXPECT_LT((est->q_world_body * up_body - Eigen::Vector3d::UnitZ()).norm(), 1e-3);
  // A window with too few samples gives nothing.
  EXPECT_FALSE(dsp::estimate_static_imu(samples, 0, 10 * kNsPerMs));
}

TEST(StaticImu, MatchesGroundTruthOnTheRealRecording) {
  const auto rec = recording::read_euroc(bundled_recording());
  const auto& frames = rec.cams[0].frames;
  const auto est = dsp::estimate_static_imu(rec.imu, frames.front().t_ns, frames.back().t_ns);
  ASSERT_TRUE(est);
  EXPECT_TRUE(dsp::is_still(*est));
  const auto& gt = rec.ground_truth.front();
  const Eigen::Vector3d up_body = gt.T_world_body.linear().transpose() * Eigen::Vector3d::UnitZ();
  const double angle_deg = std::acos(est->mean_accel_m_s2.normalized().dot(up_body)) * 180.0 / M_PI;
  EXPECT_LT(angle_deg, 1.0);  // the data README reports 0.6 degrees over all 95 frames
  EXPECT_LT((est->gyro_bias_rad_s - gt.gyro_bias_rad_s).norm(), 0.003);
  EXPECT_NEAR(est->mean_accel_m_s2.norm(), 9.81, 0.1);
}

}  // namespace
}  // namespace wallar::test
