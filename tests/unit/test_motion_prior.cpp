// SPDX-License-Identifier: Apache-2.0
/// @file test_motion_prior.cpp
/// @brief The tracker's prediction: gyro integration (bias, camera-IMU time offset, ring halves,
/// extrapolation) and the predicted pose of a fast turn far from the world origin.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "wallar/dsp/imu/gyro_integration.hpp"
#include "wallar/dsp/tracking/tracker.hpp"

namespace wallar {
namespace {

constexpr double kPi = 3.14159265358979323846;

double angle_between(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return Eigen::AngleAxisd(a.conjugate() * b).angle();
}

/// Samples at rate_hz over [t0, t1] (IMU clock) of a rotation about `axis` at `rate` plus a
/// constant bias.
std::vector<ImuSample> constant_turn(TimeNs t0, TimeNs t1, double rate_hz, const Eigen::Vector3d& w,
                                     const Eigen::Vector3d& bias) {
  std::vector<ImuSample> out;
  const DurationNs dt = static_cast<DurationNs>(1e9 / rate_hz);
  for (TimeNs t = t0; t <= t1; t += dt) {
    ImuSample s;
    s.t_ns = t;
    s.gyro_rad_s = w + bias;
    out.push_back(s);
  }
  return out;
}

TEST(GyroIntegration, BiasIsSubtractedAndTheIntervalIsShiftedToTheImuClock) {
  const Eigen::Vector3d w(0.0, 5.236, 0.0);  // 300 deg/s about y
  const Eigen::Vector3d bias(0.01, -0.02, 0.005);
  // The IMU clock runs 7 ms ahead of the camera's: t_imu = t_cam + 7 ms. Make the rate change
  // at IMU time 57 ms (camera time 50 ms), so a wrong shift integrates the wrong part.
  std::vector<ImuSample> samples =
      constant_turn(0, 57 * kNsPerMs, 1000.0, Eigen::Vector3d::Zero(), bias);
  const std::vector<ImuSample> turn = constant_turn(58 * kNsPerMs, 200 * kNsPerMs, 1000.0, w, bias);
  samples.insert(samples.end(), turn.begin(), turn.end());
  dsp::GyroIntegrationOptions options;
  options.timeshift_cam_imu_ns = 7 * kNsPerMs;
  // Camera interval (50, 100] ms: the turn for 50 ms = 15 deg (less the 1 ms ramp's half).
  const dsp::GyroDelta d =
      dsp::integrate_gyro(samples, {}, 50 * kNsPerMs, 100 * kNsPerMs, bias, options);
  ASSERT_TRUE(d.valid);
  const double expected = 5.236 * 0.0495;
  EXPECT_NEAR(Eigen::AngleAxisd(d.q_start_end).angle(), expected, 1e-3);
  EXPECT_NEAR(std::abs(Eigen::AngleAxisd(d.q_start_end).axis().y()), 1.0, 1e-6);
  // Without the shift, 7 ms of the turn are missed (0.037 rad): the offset matters.
  const dsp::GyroDelta unshifted =
      dsp::integrate_gyro(samples, {}, 50 * kNsPerMs, 100 * kNsPerMs, bias);
  EXPECT_GT(std::abs(Eigen::AngleAxisd(unshifted.q_start_end).angle() - expected), 0.03);
  // Without the bias correction the angle is off by |bias| * 50 ms per axis.
  const dsp::GyroDelta biased = dsp::integrate_gyro(samples, {}, 50 * kNsPerMs, 100 * kNsPerMs,
                                                    Eigen::Vector3d::Zero(), options);
  EXPECT_GT(angle_between(biased.q_start_end, d.q_start_end), 0.0009);
}

TEST(GyroIntegration, RingHalvesAndAShortGapAtTheEndAreCovered) {
  const Eigen::Vector3d w(0.3, 0.0, 2.0);
  const std::vector<ImuSample> samples =
      constant_turn(0, 95 * kNsPerMs, 200.0, w, Eigen::Vector3d::Zero());
  // Split as a ring holds them; the frame at 100 ms comes before the IMU sample at 100 ms.
  const std::span<const ImuSample> all(samples);
  const dsp::GyroDelta d = dsp::integrate_gyro(all.first(7), all.subspan(7), 40 * kNsPerMs,
                                               100 * kNsPerMs, Eigen::Vector3d::Zero());
  ASSERT_TRUE(d.valid);
  EXPECT_NEAR(d.covered_s, 0.060, 1e-9);
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(w.norm() * 0.060, w.normalized()));
  EXPECT_LT(angle_between(d.q_start_end, truth), 1e-9);
  // An interval the samples do not reach is not a prior.
  EXPECT_FALSE(
      dsp::integrate_gyro(samples, {}, 300 * kNsPerMs, 350 * kNsPerMs, Eigen::Vector3d::Zero())
          .valid);
}

/// Camera centre of T_cam_world.
Eigen::Vector3d centre(const SE3d& T_cw) { return -T_cw.linear().transpose() * T_cw.translation(); }

TEST(MotionPrior, AFastTurnFarFromTheOriginKeepsThePredictedCentreOnThePath) {
  // A head 12 m from the world origin walking at 1.4 m/s along x, looking ahead, that starts a
  // quick turn at 300 deg/s about the vertical (the camera's -y) between frames 1 and 2 (30 Hz).
  const double dt = 1.0 / 30.0, rate = 300.0 * kPi / 180.0;
  const auto pose_at = [&](int k, double yaw) {
    const Eigen::Vector3d c(8.0 + 1.4 * dt * k, 9.0, 1.6);
    const Eigen::Matrix3d R_world_cam =
        Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
        (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
    SE3d T_wc = SE3d::Identity();
    T_wc.linear() = R_world_cam;
    T_wc.translation() = c;
    return SE3d(T_wc.inverse());
  };
  const SE3d T0 = pose_at(0, 0.0), T1 = pose_at(1, 0.0), T2 = pose_at(2, rate * dt);
  const SE3d velocity = T1 * T0.inverse();
  // The gyro's rotation of the camera from frame 1 to frame 2 (exact here: 10 deg).
  dsp::RotationPrior gyro;
  gyro.valid = true;
  gyro.q_prev_cur = Eigen::Quaterniond(T1.linear() * T2.linear().transpose());
  const SE3d predicted = dsp::predict_camera_pose(T1, velocity, gyro);
  EXPECT_LT((centre(predicted) - centre(T2)).norm(), 0.01);
  EXPECT_LT(Eigen::AngleAxisd(predicted.linear() * T2.linear().transpose()).angle(), 1e-9);
  // Without the gyro the centre is as good, the rotation is the turn's 10 deg behind.
  const SE3d no_gyro = dsp::predict_camera_pose(T1, velocity, {});
  EXPECT_LT((centre(no_gyro) - centre(T2)).norm(), 0.01);
  EXPECT_NEAR(Eigen::AngleAxisd(no_gyro.linear() * T2.linear().transpose()).angle(), rate * dt,
              1e-9);
  // The old prior (velocity * T_cw with the gyro's rotation swapped in, translation kept)
  // swung the centre about the world origin: the turn's angle times the distance, 2 m here.
  SE3d old = velocity * T1;
  old.linear() = gyro.q_prev_cur.conjugate().toRotationMatrix() * T1.linear();
  EXPECT_GT((centre(old) - centre(T2)).norm(), 1.5);
}

TEST(MotionPrior, TheGyrosTrustShrinksWithTheTimeSinceTheLastTrackedFrame) {
  // A residual bias turns the integrated rotation in proportion to the interval: a tracker that
  // skips frames (a slow board, TCG) must trust the gyro less for the longer span, or the pose
  // follows the bias instead of the map.
  dsp::TrackerConfig config;
  config.gyro_rotation_sigma_deg = 0.01;
  config.gyro_sigma_interval_s = 0.05;
  EXPECT_DOUBLE_EQ(dsp::gyro_prior_sigma_deg(config, 0.0), 0.01);    // first frame
  EXPECT_DOUBLE_EQ(dsp::gyro_prior_sigma_deg(config, 0.033), 0.01);  // 30 Hz: as configured
  EXPECT_DOUBLE_EQ(dsp::gyro_prior_sigma_deg(config, 0.05), 0.01);
  EXPECT_NEAR(dsp::gyro_prior_sigma_deg(config, 0.3), 0.06, 1e-12);  // six frames' span
  config.gyro_rotation_sigma_deg = 0.0;                              // the gyro only seeds
  EXPECT_DOUBLE_EQ(dsp::gyro_prior_sigma_deg(config, 0.3), 0.0);
}

}  // namespace
}  // namespace wallar
