// SPDX-License-Identifier: Apache-2.0
/// @file test_motion_prior.cpp
/// @brief The tracker's prediction: gyro integration (bias, camera-IMU time offset, ring halves,
/// extrapolation), the predicted pose of a fast turn far from the world origin, and the head's
/// pivot learnt from tracked poses.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "wallar/dsp/imu/gyro_integration.hpp"
#include "wallar/dsp/tracking/head_pivot.hpp"
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

/// A head on a neck: the pivot walks at `walk_m_s` along x (bobbing by `bob_m`), the head yaws
/// through quick turns (peaking near 260 deg/s) and nods; the camera centre sits `lever_cam`
/// from the pivot in the camera frame. T_cam_world at t_s.
SE3d head_on_neck(double t_s, const Eigen::Vector3d& lever_cam, double walk_m_s, bool turns,
                  double bob_m = 0.025) {
  const double yaw = turns ? 0.9 * std::sin(2.0 * kPi * 0.8 * t_s) : 0.0;
  const double pitch = turns ? 0.3 * std::sin(2.0 * kPi * 0.5 * t_s + 1.0) : 0.0;
  const Eigen::Matrix3d R_world_cam =
      Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
      Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()).toRotationMatrix() *
      (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
  const Eigen::Vector3d pivot(5.0 + walk_m_s * t_s, -3.0,
                              1.5 + bob_m * std::cos(2.0 * kPi * 1.8 * t_s));
  SE3d T_wc = SE3d::Identity();
  T_wc.linear() = R_world_cam;
  T_wc.translation() = pivot + R_world_cam * lever_cam;
  return SE3d(T_wc.inverse());
}

TEST(HeadPivot, LearnsTheLeverOfAHeadTurningOnItsNeckAndPredictsTheTurnsArc) {
  // Camera 11 cm ahead of the neck, 6 cm above it, 3 cm to its side (camera frame: x right,
  // y down, z ahead), walking at 0.4 m/s; 30 Hz for 3 s.
  const Eigen::Vector3d lever(-0.03, -0.06, 0.11);
  const double dt = 1.0 / 30.0;
  dsp::HeadPivot pivot;
  for (int k = 0; k < 90; ++k) {
    pivot.observe(static_cast<TimeNs>(k * dt * 1e9), head_on_neck(k * dt, lever, 0.4, true));
  }
  EXPECT_LT((pivot.lever_cam() - lever).norm(), 0.005) << pivot.lever_cam().transpose();
  // The next frames (the pivot now walking evenly), as the tracker predicts them from the last
  // two and the gyro's rotation: through the turn's slowing down the constant-velocity centre
  // is millimetres off a frame, the swing about the learnt pivot a tenth of that.
  double worst_pivot = 0.0, worst_constant = 0.0;
  for (int k = 90; k < 110; ++k) {
    const SE3d T0 = head_on_neck((k - 1) * dt, lever, 0.4, true, 0.0);
    const SE3d T1 = head_on_neck(k * dt, lever, 0.4, true, 0.0);
    const SE3d T2 = head_on_neck((k + 1) * dt, lever, 0.4, true, 0.0);
    dsp::RotationPrior gyro;
    gyro.valid = true;
    gyro.q_prev_cur = Eigen::Quaterniond(T1.linear() * T2.linear().transpose());
    const SE3d velocity = T1 * T0.inverse();
    const SE3d swung = dsp::predict_camera_pose(T1, velocity, gyro, pivot.lever_cam());
    const SE3d constant = dsp::predict_camera_pose(T1, velocity, gyro);
    worst_pivot = std::max(worst_pivot, (centre(swung) - centre(T2)).norm());
    worst_constant = std::max(worst_constant, (centre(constant) - centre(T2)).norm());
  }
  EXPECT_GT(worst_constant, 0.002);
  EXPECT_LT(worst_pivot, 0.1 * worst_constant) << worst_pivot;
}

TEST(HeadPivot, ARigThatDoesNotTurnLearnsNoLever) {
  // Walking straight with a bob (the centre's velocity changes, the rotation does not): nothing
  // ties the velocity changes to a turn, so the prediction stays the constant-velocity one.
  const Eigen::Vector3d lever(-0.03, -0.06, 0.11);
  const double dt = 1.0 / 30.0;
  dsp::HeadPivot pivot;
  for (int k = 0; k < 300; ++k) {
    pivot.observe(static_cast<TimeNs>(k * dt * 1e9), head_on_neck(k * dt, lever, 1.4, false));
  }
  EXPECT_LT(pivot.lever_cam().norm(), 1e-6);
  // Poses out of order or a broken history add nothing either.
  pivot.observe(0, head_on_neck(0.0, lever, 1.4, true));
  pivot.break_history();
  pivot.observe(1, head_on_neck(0.5, lever, 1.4, true));
  EXPECT_LT(pivot.lever_cam().norm(), 1e-6);
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
