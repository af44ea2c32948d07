// SPDX-License-Identifier: Apache-2.0
// The accelerometer bias and magnetometer iron fits (dsp/imu/imu_intrinsics.hpp), and the
// attitude filter applying them.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "wallar/dsp/imu/attitude_filter.hpp"
#include "wallar/dsp/imu/imu_intrinsics.hpp"

namespace wallar::dsp::intrinsics_test {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kG = 9.81;

Eigen::Matrix3d R_world_body(double yaw_deg, double pitch_deg, double roll_deg) {
  return (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

// A still accelerometer: the reaction to gravity in the body frame, plus bias and noise.
Eigen::Vector3d still_accel(const Eigen::Matrix3d& R, const Eigen::Vector3d& bias, double noise,
                            std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, noise);
  return R.transpose() * Eigen::Vector3d(0.0, 0.0, kG) + bias +
         Eigen::Vector3d(n(rng), n(rng), n(rng));
}

TEST(AccelBias, FiveTiltsHeldStillGiveTheBiasWithinAMilliG) {
  std::mt19937_64 rng(3);
  const Eigen::Vector3d bias(0.06, -0.04, 0.08);
  std::vector<Eigen::Vector3d> means;
  for (const auto& [pitch, roll] :
       std::vector<std::pair<double, double>>{{0, 0}, {45, 0}, {-40, 0}, {0, 45}, {0, -45}}) {
    for (const double yaw : {0.0, 90.0, 180.0, 270.0}) {
      means.push_back(still_accel(R_world_body(yaw, pitch, roll), bias, 0.002, rng));
    }
  }
  const AccelBiasFit fit = fit_accel_bias(means, kG);
  ASSERT_TRUE(fit.solved);
  EXPECT_LT((fit.bias_m_s2 - bias).norm(), 0.005);  // 0.5 mg
  EXPECT_LT(fit.residual_rms_m_s2, 0.005);
  EXPECT_GT(fit.direction_spread, kMinAccelDirectionSpread);
}

TEST(AccelBias, PosesThatNeverTiltAreRefused) {
  std::mt19937_64 rng(4);
  std::vector<Eigen::Vector3d> means;
  for (const double yaw : {0.0, 60.0, 120.0, 180.0, 240.0, 300.0}) {
    means.push_back(
        still_accel(R_world_body(yaw, 3.0, 0.0), Eigen::Vector3d(0.05, 0, 0), 0.002, rng));
  }
  const AccelBiasFit fit = fit_accel_bias(means, kG);
  EXPECT_FALSE(fit.solved);
  EXPECT_LT(fit.direction_spread, kMinAccelDirectionSpread);
  EXPECT_FALSE(fit_accel_bias(std::span(means).first(3), kG).solved);  // fewer than four
}

TEST(StillPoses, HoldsBetweenTurnsAreFoundWithTheirMeans) {
  // 200 Hz: 1 s level, a 0.5 s pitch turn of 45 deg, 1 s held there.
  std::vector<ImuSample> samples;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0.0, 0.01);
  const Eigen::Vector3d bias(0.02, 0.0, -0.03);
  for (int k = 0; k < 500; ++k) {
    const double t = k / 200.0;
    double pitch = 0.0, rate = 0.0;
    if (t >= 1.0 && t < 1.5) {
      const double x = (t - 1.0) / 0.5;
      pitch = 45.0 * (x - std::sin(2 * std::numbers::pi * x) / (2 * std::numbers::pi));
      rate = 45.0 * kDeg / 0.5 * (1 - std::cos(2 * std::numbers::pi * x));
    } else if (t >= 1.5) {
      pitch = 45.0;
    }
    ImuSample s;
    s.t_ns = static_cast<TimeNs>(k) * 5'000'000;
    s.gyro_rad_s = Eigen::Vector3d(n(rng), rate + n(rng), n(rng));
    s.accel_m_s2 = still_accel(R_world_body(0, pitch, 0), bias, 0.02, rng);
    samples.push_back(s);
  }
  const std::vector<StillPose> poses = find_still_poses(samples);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_LT(poses[0].t_end_ns, 1'000'000'000);
  EXPECT_GE(poses[1].t_begin_ns, 1'500'000'000);
  const Eigen::Vector3d want0 =
      R_world_body(0, 0, 0).transpose() * Eigen::Vector3d(0, 0, kG) + bias;
  const Eigen::Vector3d want1 =
      R_world_body(0, 45, 0).transpose() * Eigen::Vector3d(0, 0, kG) + bias;
  EXPECT_LT((poses[0].mean_accel_m_s2 - want0).norm(), 0.01);
  EXPECT_LT((poses[1].mean_accel_m_s2 - want1).norm(), 0.01);
}

struct MagCase {
  Eigen::Vector3d field_world{20.0, 0.0, -43.0};
  Eigen::Vector3d hard{12.0, -25.0, 8.0};
  Eigen::Matrix3d soft;  // reading = soft * field_body + hard
  MagCase() { soft << 1.08, 0.04, -0.03, 0.04, 0.93, 0.05, -0.03, 0.05, 1.02; }
  Eigen::Vector3d read(const Eigen::Matrix3d& R, std::mt19937_64& rng, double noise) const {
    std::normal_distribution<double> n(0.0, noise);
    return soft * (R.transpose() * field_world) + hard + Eigen::Vector3d(n(rng), n(rng), n(rng));
  }
};

TEST(Magnetometer, AnEllipsoidOverManyOrientationsGivesHardAndSoftIron) {
  const MagCase c;
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> readings;
  std::vector<Eigen::Matrix3d> attitudes;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Matrix3d R =
        Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng)).normalized())
            .toRotationMatrix();
    attitudes.push_back(R);
    readings.push_back(c.read(R, rng, 0.3));
  }
  const double B = c.field_world.norm();
  const MagnetometerFit fit = fit_magnetometer(readings, B);
  ASSERT_TRUE(fit.solved);
  EXPECT_LT((fit.hard_iron_uT - c.hard).norm(), 0.3);
  // S undoes the soft iron: S * soft = I (a symmetric soft iron has a symmetric inverse).
  EXPECT_LT((fit.soft_iron * c.soft - Eigen::Matrix3d::Identity()).norm(), 0.01);
  EXPECT_NEAR(fit.field_uT, B, 1e-9);
  EXPECT_LT(fit.residual_rms_uT, 0.4);
  EXPECT_GT(fit.coverage, 0.2);
  // The corrected field's heading in the world is the field's own (0) in every attitude.
  double worst_deg = 0.0;
  for (std::size_t i = 0; i < readings.size(); i += 10) {
    const double h =
        field_heading_rad(attitudes[i], fit.soft_iron * (readings[i] - fit.hard_iron_uT));
    worst_deg = std::max(worst_deg, std::abs(h) / kDeg);
  }
  EXPECT_LT(worst_deg, 3.0);
  // Without a field strength: the sensor's scale (det S = 1), the same shape.
  const MagnetometerFit own = fit_magnetometer(readings);
  ASSERT_TRUE(own.solved);
  EXPECT_NEAR(own.soft_iron.determinant(), 1.0, 1e-9);
  EXPECT_LT((own.hard_iron_uT - c.hard).norm(), 0.3);
  EXPECT_LT((own.soft_iron / own.field_uT - fit.soft_iron / B).norm(), 1e-3);
}

TEST(Magnetometer, TurnsAboutOneAxisOnlyAreRefused) {
  const MagCase c;
  std::mt19937_64 rng(7);
  std::vector<Eigen::Vector3d> readings;
  for (int i = 0; i < 720; ++i) readings.push_back(c.read(R_world_body(i * 0.5, 0, 0), rng, 0.3));
  EXPECT_FALSE(fit_magnetometer(readings, c.field_world.norm()).solved);
  EXPECT_FALSE(fit_magnetometer(std::span(readings).first(20)).solved);  // too few
}

TEST(AttitudeFilterCalibration, TheAccelerometerBiasIsRemovedBeforeTheTilt) {
  // A level IMU at rest whose accelerometer reads 0.1 m/s^2 too much along x: uncorrected the
  // filter takes that as a 0.58 deg tilt; with the calibration's bias it is level.
  const Eigen::Vector3d bias(0.1, 0.0, 0.0);
  std::mt19937_64 rng(8);
  auto tilt_deg = [&](const AttitudeFilterConfig& config) {
    AttitudeFilter f(config);
    for (int k = 0; k < 600; ++k) {
      ImuSample s;
      s.t_ns = static_cast<TimeNs>(k) * 5'000'000;
      s.accel_m_s2 = still_accel(Eigen::Matrix3d::Identity(), bias, 0.01, rng);
      f.update(s);
    }
    EXPECT_TRUE(f.initialized());
    return tilt_error_rad(f.q_world_imu(), Eigen::Quaterniond::Identity()) / kDeg;
  };
  AttitudeFilterConfig raw;
  EXPECT_GT(tilt_deg(raw), 0.5);
  AttitudeFilterConfig calibrated;
  calibrated.accel_bias_m_s2 = bias;
  EXPECT_LT(tilt_deg(calibrated), 0.05);
}

TEST(AttitudeFilterCalibration, TheMagnetometerIronIsRemovedBeforeTheHeading) {
  // Turning 90 deg about z on the gyro: the heading update must agree with the gyro when the
  // field is corrected, and pulls the yaw off when the hard iron is left in.
  const MagCase c;
  std::mt19937_64 rng(9);
  auto yaw_error_deg = [&](const AttitudeFilterConfig& config) {
    AttitudeFilter f(config);
    const int n = 2000;  // 10 s at 200 Hz: 1 s still, a 90 deg turn over 4 s, 5 s still
    for (int k = 0; k < n; ++k) {
      const double t = k / 200.0;
      const double x = std::clamp((t - 1.0) / 4.0, 0.0, 1.0);
      const double yaw = 90.0 * (x - std::sin(2 * std::numbers::pi * x) / (2 * std::numbers::pi));
      const double rate =
          (t > 1.0 && t < 5.0) ? 90.0 * kDeg / 4.0 * (1 - std::cos(2 * std::numbers::pi * x)) : 0.0;
      ImuSample s;
      s.t_ns = static_cast<TimeNs>(k) * 5'000'000;
      s.gyro_rad_s = Eigen::Vector3d(0, 0, rate);
      const Eigen::Matrix3d R = R_world_body(yaw, 0, 0);
      s.accel_m_s2 = R.transpose() * Eigen::Vector3d(0, 0, kG);
      s.mag_uT = c.read(R, rng, 0.3);
      f.update(s);
    }
    // The filter's yaw is relative to its start: the truth turned 90 deg.
    const Eigen::Vector3d x_world = f.q_world_imu() * Eigen::Vector3d::UnitX();
    const Eigen::Vector3d x0_world = f.initial_estimate().q_world_body * Eigen::Vector3d::UnitX();
    const double turned = std::atan2(x0_world.cross(x_world).z(), x0_world.dot(x_world)) / kDeg;
    return std::abs(turned - 90.0);
  };
  AttitudeFilterConfig raw;
  AttitudeFilterConfig calibrated;
  calibrated.mag_hard_iron_uT = c.hard;
  calibrated.mag_soft_iron = c.soft.inverse();
  const double raw_error = yaw_error_deg(raw), calibrated_error = yaw_error_deg(calibrated);
  EXPECT_LT(calibrated_error, 1.0);
  EXPECT_GT(raw_error, 5.0 * calibrated_error);
}

}  // namespace wallar::dsp::intrinsics_test
