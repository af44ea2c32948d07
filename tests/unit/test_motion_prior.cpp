// SPDX-License-Identifier: Apache-2.0
/// @file test_motion_prior.cpp
/// @brief The tracker's prediction: gyro integration (bias, camera-IMU time offset, ring halves,
/// extrapolation) and the predicted pose of a fast turn far from the world origin.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "wallar/dsp/imu/gyro_integration.hpp"
#include "wallar/dsp/tracking/accel_prediction.hpp"
#include "wallar/dsp/tracking/synthetic_motion.hpp"
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

/// A standing head's quick turns (synth-rig's model, 300 deg/s peak) seen at 20 Hz by a 200 Hz
/// IMU: the IMU's next position from its last two poses and the specific force against the
/// truth, in the frames of the turns (where the camera swings about the neck).
struct TurnFigures {
  double accel_max_mm = 0.0, accel_rms_mm = 0.0, constant_velocity_max_mm = 0.0;
  double gravity_max_err_m_s2 = 0.0;
  int turn_frames = 0;
};

TurnFigures predict_through_quick_turns(const ImuCalibration& noise) {
  const dsp::SyntheticRoom room = dsp::headset_room(1);
  dsp::HeadMotionConfig mc;
  mc.motion = dsp::HeadMotion::kQuickTurns;
  mc.seed = 9;
  mc.duration_s = 12.0;
  const dsp::HeadMotionModel model(room, mc);
  dsp::SyntheticImuConfig ic;
  ic.noise = noise;
  ic.rate_hz = 200.0;
  ic.accel_bias0_m_s2 = Eigen::Vector3d(0.05, 0.01, -0.09);  // not known to the prediction
  dsp::SyntheticImu imu(model, ic, 0, 0);
  std::vector<ImuSample> samples;
  while (imu.next_truth_t_ns() <= 13 * kNsPerS) samples.push_back(imu.next().sample);
  const DurationNs frame_ns = 50 * kNsPerMs;
  const auto t_of = [&](int k) { return static_cast<TimeNs>(k) * frame_ns; };
  const auto force = [&](int k) {  // the interval (k - 1, k]
    const dsp::GyroDelta d =
        dsp::integrate_gyro(samples, {}, t_of(k - 1), t_of(k), Eigen::Vector3d::Zero());
    EXPECT_TRUE(d.valid);
    return dsp::SpecificForceInterval{d.dv_m_s, d.dp_m, ns_to_s(frame_ns)};
  };
  const Eigen::Vector3d g(0.0, 0.0, -ic.gravity_m_s2);
  TurnFigures f;
  double sum_sq = 0.0;
  for (int k = 2; t_of(k + 1) <= 12 * kNsPerS; ++k) {
    const dsp::BodyMotionState truth = model.state(ns_to_s(t_of(k + 1)));
    if (truth.omega_body_rad_s.norm() < 100.0 * kPi / 180.0) continue;  // not in a turn
    const SE3d T0 = model.T_world_body(ns_to_s(t_of(k - 1)));
    const SE3d T1 = model.T_world_body(ns_to_s(t_of(k)));
    const dsp::SpecificForceInterval last = force(k), next = force(k + 1);
    const Eigen::Vector3d p = dsp::predict_imu_position(T0, T1, last, next, g);
    const double e_mm = 1000.0 * (p - truth.T_world_body.translation()).norm();
    const Eigen::Vector3d cv = 2.0 * T1.translation() - T0.translation();
    f.accel_max_mm = std::max(f.accel_max_mm, e_mm);
    sum_sq += e_mm * e_mm;
    f.constant_velocity_max_mm = std::max(f.constant_velocity_max_mm,
                                          1000.0 * (cv - truth.T_world_body.translation()).norm());
    const Eigen::Vector3d g_est = dsp::gravity_from_poses(T0, T1, truth.T_world_body, last, next);
    f.gravity_max_err_m_s2 = std::max(f.gravity_max_err_m_s2, (g_est - g).norm());
    ++f.turn_frames;
  }
  f.accel_rms_mm = std::sqrt(sum_sq / std::max(1, f.turn_frames));
  return f;
}

TEST(AccelPrediction, AQuickTurnsSwingIsPredictedThroughTheSpecificForce) {
  // A perfect IMU (but for an accelerometer bias nobody calibrated).
  const TurnFigures exact = predict_through_quick_turns(ImuCalibration{});
  ASSERT_GT(exact.turn_frames, 10);
  EXPECT_LT(exact.accel_max_mm, 0.5);
  EXPECT_LT(exact.gravity_max_err_m_s2, 0.5);
  // Constant velocity misses where the turn speeds up and slows down.
  EXPECT_GT(exact.constant_velocity_max_mm, 5.0);
  // The headset's consumer MEMS noise (ICM-20948-like densities).
  const TurnFigures noisy = predict_through_quick_turns(dsp::default_headset_rig().imu);
  EXPECT_LT(noisy.accel_rms_mm, 1.0);
  EXPECT_LT(noisy.accel_max_mm, 2.0);
  std::printf(
      "quick turns, %d frames: accel max %.3f mm (noisy %.3f, rms %.3f), constant "
      "velocity max %.2f mm, gravity err max %.3f m/s^2 (noisy %.3f)\n",
      exact.turn_frames, exact.accel_max_mm, noisy.accel_max_mm, noisy.accel_rms_mm,
      exact.constant_velocity_max_mm, exact.gravity_max_err_m_s2, noisy.gravity_max_err_m_s2);
}

TEST(AccelPrediction, AFirstGravityTakenWhileTheHeadAcceleratedIsAveragedAwayAndLaterJumpsGated) {
  const Eigen::Vector3d g(0.0, 0.0, -9.81);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);  // one frame's estimate: about 1 m/s^2
  const auto estimate = [&] {
    return Eigen::Vector3d(g + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  };
  // The first estimate (the specific force alone) taken in a 6 m/s^2 swing of the head.
  dsp::GravityEstimate gravity({.average_frames = 100, .gate_m_s2 = 4.0, .gate_after = 20});
  EXPECT_TRUE(gravity.add(g + Eigen::Vector3d(6.0, 0.0, 0.0)));
  // The right ones are not shut out by it (all further than the gate from the first).
  int kept = 0;
  for (int k = 0; k < 200; ++k) kept += gravity.add(estimate()) ? 1 : 0;
  EXPECT_GE(kept, 195);
  EXPECT_LT((gravity.value() - g).norm(), 0.3);
  // Once averaged, a pose that jumped (a relocalisation) is dropped.
  const Eigen::Vector3d before = gravity.value();
  EXPECT_FALSE(gravity.add(g + Eigen::Vector3d(0.0, 9.0, 0.0)));
  EXPECT_FALSE(gravity.add(Eigen::Vector3d(NAN, 0.0, 0.0)));
  EXPECT_EQ(gravity.value(), before);
  // A correction turning the world turns gravity with it; a reset starts again.
  gravity.rotate(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()).toRotationMatrix());
  EXPECT_NEAR(gravity.value().norm(), before.norm(), 1e-12);
  EXPECT_GT((gravity.value() - before).norm(), 0.5);
  gravity.reset();
  EXPECT_EQ(gravity.samples(), 0);
  EXPECT_TRUE(gravity.add(g));
  EXPECT_EQ(gravity.value(), g);
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
