// SPDX-License-Identifier: Apache-2.0
/// @file test_attitude_filter.cpp
/// @brief The attitude filter on synthetic motion with known truth, and on the real EuRoC V1_01
/// flight against its ground truth (the accuracy targets of docs/results.md).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "test_support.hpp"
#include "wallar/dsp/imu/attitude_errors.hpp"
#include "wallar/dsp/imu/attitude_filter.hpp"
#include "wallar/firmware/imu_attitude.hpp"

namespace wallar::test {
namespace {

constexpr double kDeg = 180.0 / M_PI;

// Deterministic noise (no std::*_distribution: identical on x86 and aarch64): a 64-bit LCG,
// and the sum of four uniforms as a roughly normal variate of unit variance.
class Noise {
 public:
  explicit Noise(std::uint64_t seed) : state_(seed) {}
  double uniform() {  // [0, 1)
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state_ >> 11) * 0x1.0p-53;
  }
  double normal() {
    double s = 0.0;
    for (int i = 0; i < 4; ++i) s += uniform();
    return (s - 2.0) * std::sqrt(3.0);
  }
  Eigen::Vector3d normal3() { return {normal(), normal(), normal()}; }

 private:
  std::uint64_t state_;
};

struct Synthetic {
  std::vector<ImuSample> samples;
  std::vector<Eigen::Quaterniond> q_world_imu;  //!< truth at each sample
};

struct MotionSpec {
  double still_s = 2.0;     //!< at rest first
  double moving_s = 60.0;   //!< then turning
  double rate_scale = 1.0;  //!< 0: stays still
  Eigen::Vector3d gyro_bias_rad_s{0.01, -0.02, 0.015};
  double gyro_noise_rad_s = 0.005;
  double accel_noise_m_s2 = 0.05;
  bool with_mag = false;
  bool shake_first_window = false;  //!< the first second is not still
  Eigen::Quaterniond q_start =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 0).normalized()));
};

Eigen::Vector3d rate_at(double t_s, const MotionSpec& m) {
  return m.rate_scale * Eigen::Vector3d(0.5 * std::sin(0.7 * t_s), 0.4 * std::sin(0.5 * t_s + 1.0),
                                        0.6 * std::cos(0.3 * t_s));
}

// 200 Hz samples of a body turning with rate_at() after the still part; truth integrated at
// 2 kHz. Gravity 9.81, field 48 uT dipping 60 degrees.
Synthetic make_motion(const MotionSpec& m, std::uint64_t seed) {
  Synthetic out;
  Noise noise(seed);
  const Eigen::Vector3d mag_world(24.0, 0.0, -41.6);
  Eigen::Quaterniond q = m.q_start;
  const int total = static_cast<int>((m.still_s + m.moving_s) * 200.0);
  for (int i = 0; i < total; ++i) {
    const double t_s = i / 200.0;
    const bool moving = t_s >= m.still_s;
    const bool shaking = m.shake_first_window && t_s < 1.0;
    Eigen::Vector3d w = moving ? rate_at(t_s - m.still_s, m) : Eigen::Vector3d::Zero();
    if (shaking) w = Eigen::Vector3d(2.0 * std::sin(40.0 * t_s), 0.0, 0.0);
    ImuSample s;
    s.t_ns = kNsPerS + i * 5 * kNsPerMs;
    s.gyro_rad_s = w + m.gyro_bias_rad_s + m.gyro_noise_rad_s * noise.normal3();
    s.accel_m_s2 =
        q.conjugate() * Eigen::Vector3d(0.0, 0.0, 9.81) + m.accel_noise_m_s2 * noise.normal3();
    if (m.with_mag) s.mag_uT = q.conjugate() * mag_world + 0.5 * noise.normal3();
    out.samples.push_back(s);
    out.q_world_imu.push_back(q);
    if (shaking) continue;          // a shake that returns where it started
    for (int k = 0; k < 10; ++k) {  // truth to the next sample, at 2 kHz
      const double tk = t_s + (k + 0.5) / 2000.0;
      const Eigen::Vector3d wk =
          tk >= m.still_s ? rate_at(tk - m.still_s, m) : Eigen::Vector3d::Zero();
      const double angle = wk.norm() / 2000.0;
      if (angle > 0.0) q = (q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, wk.normalized())));
    }
    q.normalize();
  }
  return out;
}

double yaw_of(const Eigen::Quaterniond& q_world_imu) {
  // Heading of the IMU x axis projected on the horizontal plane.
  const Eigen::Vector3d x_world = q_world_imu * Eigen::Vector3d::UnitX();
  return std::atan2(x_world.y(), x_world.x());
}

TEST(AttitudeFilter, StartsFromTheFirstStillWindowAndTakesItsGravityAndBias) {
  MotionSpec m;
  m.still_s = 3.0;
  m.moving_s = 0.0;
  m.shake_first_window = true;
  const Synthetic syn = make_motion(m, 1);
  dsp::AttitudeFilter filter;  // a 200-sample window
  std::size_t first_valid = 0;
  for (std::size_t i = 0; i < syn.samples.size(); ++i) {
    if (filter.update(syn.samples[i]) && first_valid == 0) first_valid = i;
  }
  ASSERT_TRUE(filter.initialized());
  // The shaken first second is refused; the window [0.5 s, 1.5 s) still holds shaking; the one
  // sliding in at 1 s [1.0, 2.0) is the first still one.
  EXPECT_GE(filter.counters().init_windows_rejected, 1u);
  EXPECT_EQ(first_valid, 399u);
  EXPECT_GE(filter.initial_estimate().t_begin_ns, syn.samples[200].t_ns);
  EXPECT_LT(dsp::tilt_error_rad(filter.q_world_imu(), syn.q_world_imu.back()) * kDeg, 0.2);
  EXPECT_LT((filter.gyro_bias_rad_s() - m.gyro_bias_rad_s).norm(), 1e-3);
  EXPECT_NEAR(filter.gravity_dir_imu().norm(), 1.0, 1e-12);
}

TEST(AttitudeFilter, RowsBeforeTheStillWindowHaveNoEstimateAndItsOwnRowsShareIt) {
  MotionSpec m;
  m.still_s = 3.0;
  m.moving_s = 1.0;
  m.shake_first_window = true;
  recording::EurocRecording rec;
  rec.imu = make_motion(m, 5).samples;
  std::vector<firmware::AttitudeRow> rows;
  const firmware::AttitudeRun run =
      firmware::run_attitude_filter(rec, dsp::AttitudeFilterConfig{},
                                    [&rows](const firmware::AttitudeRow& r) { rows.push_back(r); });
  ASSERT_EQ(rows.size(), rec.imu.size());
  EXPECT_FALSE(run.errors);  // no ground truth
  // The still window that started the filter is samples 200..399 (see the test above).
  EXPECT_EQ(run.valid_rows, rec.imu.size() - 200);
  EXPECT_FALSE(rows[199].valid);
  EXPECT_TRUE(rows[200].valid);
  for (std::size_t i = 0; i < rows.size(); ++i) ASSERT_EQ(rows[i].t_ns, rec.imu[i].t_ns);
  EXPECT_EQ(rows[200].q_world_imu.coeffs(), rows[399].q_world_imu.coeffs());
}

TEST(AttitudeFilter, FollowsTiltAndLearnsAllThreeBiasAxesWhileTurning) {
  MotionSpec m;
  const Synthetic syn = make_motion(m, 2);
  dsp::AttitudeFilterConfig cfg;
  cfg.initial_bias_std_rad_s = 0.03;
  dsp::AttitudeFilter filter(cfg);
  // Start with a wrong bias: the still-window bias is replaced by zero, so the filter must learn
  // it.
  dsp::StaticImuEstimate start;
  start.mean_accel_m_s2 = syn.q_world_imu[0].conjugate() * Eigen::Vector3d(0.0, 0.0, 9.81);
  start.q_world_body = syn.q_world_imu[0];
  filter.initialize(start, syn.samples[0].t_ns);
  double worst_tilt_deg = 0.0;
  for (std::size_t i = 1; i < syn.samples.size(); ++i) {
    ASSERT_TRUE(filter.update(syn.samples[i]));
    if (i > 200 * 20) {
      worst_tilt_deg = std::max(
          worst_tilt_deg, dsp::tilt_error_rad(filter.q_world_imu(), syn.q_world_imu[i]) * kDeg);
    }
  }
  EXPECT_LT(worst_tilt_deg, 0.5);
  EXPECT_LT((filter.gyro_bias_rad_s() - m.gyro_bias_rad_s).norm(), 1.5e-3)
      << filter.gyro_bias_rad_s().transpose();
  EXPECT_EQ(filter.counters().accel_rejected, 0u);
  EXPECT_LT(filter.tilt_std_rad() * kDeg, 1.0);
}

TEST(AttitudeFilter, MagnetometerHoldsTheHeadingThatTheGyroBiasWouldTurn) {
  // At rest with the z axis up: the z gyro bias is invisible to the accelerometer, so the
  // heading drifts with it; the magnetometer stops the drift and reveals the bias.
  MotionSpec m;
  m.still_s = 60.0;
  m.moving_s = 0.0;
  m.q_start = Eigen::Quaterniond::Identity();
  m.gyro_bias_rad_s = Eigen::Vector3d(0.0, 0.0, 0.0);
  Synthetic syn = make_motion(m, 3);
  const Eigen::Vector3d extra_bias(0.0, 0.0, 0.01);  // appears after the still window
  for (std::size_t i = 400; i < syn.samples.size(); ++i) syn.samples[i].gyro_rad_s += extra_bias;
  m.with_mag = true;
  Synthetic syn_mag = make_motion(m, 3);
  for (std::size_t i = 400; i < syn_mag.samples.size(); ++i)
    syn_mag.samples[i].gyro_rad_s += extra_bias;

  dsp::AttitudeFilter without(dsp::AttitudeFilterConfig{});
  dsp::AttitudeFilter with(dsp::AttitudeFilterConfig{});
  for (const ImuSample& s : syn.samples) without.update(s);
  for (const ImuSample& s : syn_mag.samples) with.update(s);
  EXPECT_EQ(without.counters().mag_updates, 0u);
  EXPECT_GT(with.counters().mag_updates, 10000u);
  const double yaw_drift_without = std::abs(yaw_of(without.q_world_imu())) * kDeg;
  const double yaw_drift_with = std::abs(yaw_of(with.q_world_imu())) * kDeg;
  EXPECT_GT(yaw_drift_without, 20.0);  // 0.01 rad/s over ~58 s: about 33 degrees
  EXPECT_LT(yaw_drift_with, 2.0);
  EXPECT_NEAR(with.gyro_bias_rad_s().z(), 0.01, 1e-3);
  // The heading update never tilts: both agree that z is up.
  EXPECT_LT(dsp::tilt_error_rad(with.q_world_imu(), Eigen::Quaterniond::Identity()) * kDeg, 0.2);
}

TEST(AttitudeFilter, IgnoresNonFiniteAndOutOfOrderSamplesAndBridgesGaps) {
  MotionSpec m;
  m.moving_s = 5.0;
  Synthetic syn = make_motion(m, 4);
  syn.samples[500].gyro_rad_s.x() = std::nan("");
  syn.samples[600].t_ns = syn.samples[599].t_ns;                            // a duplicate time
  syn.samples.erase(syn.samples.begin() + 700, syn.samples.begin() + 760);  // 300 ms gap
  dsp::AttitudeFilter filter;
  for (const ImuSample& s : syn.samples) filter.update(s);
  EXPECT_EQ(filter.counters().bad_samples, 2u);
  EXPECT_EQ(filter.counters().gaps, 1u);
  EXPECT_TRUE(filter.q_world_imu().coeffs().allFinite());
  EXPECT_TRUE(filter.gyro_bias_rad_s().allFinite());
}

TEST(AttitudeFilter, GravityInTheLeftCameraFrameOfTheEurocRig) {
  const auto rec = recording::read_euroc(bundled_recording());
  const Eigen::Matrix3d R_cam_imu = rec.rig().T_cam0_imu().linear();
  dsp::AttitudeFilter filter(firmware::attitude_config_for(rec));
  for (const ImuSample& s : rec.imu) filter.update(s);
  ASSERT_TRUE(filter.initialized());
  const Eigen::Vector3d g_cam = filter.gravity_dir_in(R_cam_imu);
  // The true gravity in cam0 from ground truth: down in the world, through T_world_body and
  // T_body_cam.
  const auto& gt = rec.ground_truth.back();
  const Eigen::Vector3d g_cam_true = rec.cams[0].calib.T_body_cam.linear().transpose() *
                                     gt.T_world_body.linear().transpose() *
                                     -Eigen::Vector3d::UnitZ();
  EXPECT_LT(std::acos(std::min(1.0, g_cam.dot(g_cam_true))) * kDeg, 1.0);
  // The camera looks level-ish at the floor: gravity mostly along its +y (image down) axis.
  EXPECT_GT(g_cam.y(), 0.5);
}

TEST(AttitudeFilter, TheGyroNoiseComesFromTheImusCalibration) {
  // The rig's (or sensor.yaml's) gyro noise density and bias walk, as a datasheet or `wallar
  // calibrate imu-noise` gives them, not values tuned on one flight; without them the defaults.
  ImuCalibration imu;
  imu.rate_hz = 200.0;
  imu.gyro_noise_density = 1.7e-4;
  imu.gyro_random_walk = 1.9e-5;
  const dsp::AttitudeFilterConfig c = firmware::attitude_config_for(imu);
  EXPECT_DOUBLE_EQ(c.gyro_noise_rad_s_sqrt_hz, 1.7e-4);
  EXPECT_DOUBLE_EQ(c.gyro_bias_walk_rad_s2_sqrt_hz, 1.9e-5);
  EXPECT_EQ(c.init_window_samples, 200u);
  const dsp::AttitudeFilterConfig d = firmware::attitude_config_for(ImuCalibration{});
  EXPECT_DOUBLE_EQ(d.gyro_noise_rad_s_sqrt_hz,
                   dsp::AttitudeFilterConfig{}.gyro_noise_rad_s_sqrt_hz);
  EXPECT_DOUBLE_EQ(d.gyro_bias_walk_rad_s2_sqrt_hz,
                   dsp::AttitudeFilterConfig{}.gyro_bias_walk_rad_s2_sqrt_hz);
}

// The accelerometer's own white noise comes from the calibration too (density x sqrt(rate) per
// sample), beside the filter's motion term; an accelerometer noisier than that term is then
// trusted less, and a still head's tilt holds better than when the filter assumes a quiet one.
TEST(AttitudeFilter, TheAccelerometersNoiseComesFromTheImusCalibration) {
  ImuCalibration imu;
  imu.rate_hz = 200.0;
  imu.accel_noise_density = 0.1;  // m/s^2/sqrt(Hz): 1.41 m/s^2 per sample
  EXPECT_NEAR(firmware::attitude_config_for(imu).accel_sensor_noise_m_s2, 0.1 * std::sqrt(200.0),
              1e-12);
  EXPECT_EQ(firmware::attitude_config_for(ImuCalibration{}).accel_sensor_noise_m_s2, 0.0);
  MotionSpec m;
  m.still_s = 1.0;
  m.rate_scale = 0.5;
  m.moving_s = 30.0;
  m.accel_noise_m_s2 = 1.41;
  const Synthetic syn = make_motion(m, 7);
  const auto tilt_rms_deg = [&](double sensor_noise_m_s2) {
    dsp::AttitudeFilterConfig config;
    config.accel_sensor_noise_m_s2 = sensor_noise_m_s2;
    dsp::AttitudeFilter filter(config);
    dsp::StaticImuEstimate still;
    still.samples = 200;
    still.mean_accel_m_s2 = m.q_start.conjugate() * Eigen::Vector3d(0.0, 0.0, 9.81);
    still.gyro_bias_rad_s = m.gyro_bias_rad_s;
    still.q_world_body = m.q_start;
    filter.initialize(still, syn.samples.front().t_ns - kNsPerMs);
    double sum = 0.0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < syn.samples.size(); ++i) {
      filter.update(syn.samples[i]);
      if (i < syn.samples.size() / 2) continue;
      const double e = dsp::tilt_error_rad(filter.q_world_imu(), syn.q_world_imu[i]) * kDeg;
      sum += e * e;
      ++n;
    }
    return std::sqrt(sum / static_cast<double>(n));
  };
  const double known = tilt_rms_deg(1.41);
  const double unknown = tilt_rms_deg(0.0);
  std::printf("noisy accelerometer: tilt RMS %.3f deg with its noise known, %.3f without\n", known,
              unknown);
  EXPECT_LT(known, unknown);
}

TEST(AttitudeFilter, GroundTruthIsInterpolatedBetweenRows) {
  const auto rec = recording::read_euroc(bundled_recording());
  const auto& a = rec.ground_truth[3];
  const auto& b = rec.ground_truth[4];
  const TimeNs mid = a.t_ns + (b.t_ns - a.t_ns) / 2;
  const auto g = recording::ground_truth_at(rec.ground_truth, mid);
  ASSERT_TRUE(g);
  EXPECT_LT((g->T_world_body.translation() -
             0.5 * (a.T_world_body.translation() + b.T_world_body.translation()))
                .norm(),
            1e-6);
  EXPECT_FALSE(recording::ground_truth_at(rec.ground_truth, rec.ground_truth.front().t_ns - 1));
  EXPECT_FALSE(recording::ground_truth_at(rec.ground_truth, rec.ground_truth.back().t_ns + 1));
  EXPECT_EQ(recording::ground_truth_at(rec.ground_truth, a.t_ns)->t_ns, a.t_ns);
}

fs::path flight_recording() { return fs::path(WALLAR_TEST_DATA) / "euroc_v1_01_imu"; }

TEST(AttitudeFilter, ImuOnlyRecordingsAreReadWithoutCameras) {
  const auto rec = recording::read_euroc_imu(flight_recording());
  EXPECT_EQ(rec.imu.size(), 29120u);
  EXPECT_EQ(rec.ground_truth.size(), 2895u);
  EXPECT_DOUBLE_EQ(rec.imu_calib.rate_hz, 200.0);
  EXPECT_TRUE(rec.cams[0].frames.empty());
  TempDir tmp;
  const std::string msg = input_error_of([&] { recording::read_euroc_imu(tmp.path()); });
  EXPECT_THAT(msg, ::testing::HasSubstr("imu0: missing folder"));
}

// The accuracy targets on the real 145 s flight (docs/results.md, "IMU attitude on EuRoC V1_01").
TEST(AttitudeFilter, MeetsTheTargetsOnTheWholeEurocV101Flight) {
  const auto rec = recording::read_euroc_imu(flight_recording());
  const firmware::AttitudeRun run =
      firmware::run_attitude_filter(rec, firmware::attitude_config_for(rec));
  ASSERT_TRUE(run.errors);
  const dsp::AttitudeErrorSummary& e = *run.errors;
  EXPECT_EQ(run.valid_rows, rec.imu.size());  // the flight starts at rest
  EXPECT_GT(e.duration_s, 140.0);
  EXPECT_LT(e.tilt_rms_deg, 1.0);             // target: roll/pitch RMS under 1 degree
  EXPECT_LT(e.bias_error_final_rad_s, 2e-3);  // target: bias within 2e-3 rad/s
  EXPECT_LT(e.bias_error_rms_rad_s, 2e-3);    // ... over the last 100 s too
  EXPECT_GT(run.counters.accel_updates, 25000u);
  RecordProperty("tilt_rms_deg", std::to_string(e.tilt_rms_deg));
  std::printf(
      "tilt rms %.3f max %.3f final %.3f deg; bias final %.5f rms(last %.0f s) %.5f max %.5f; "
      "accel rejected %llu\n",
      e.tilt_rms_deg, e.tilt_max_deg, e.tilt_final_deg, e.bias_error_final_rad_s, e.bias_window_s,
      e.bias_error_rms_rad_s, e.bias_error_max_rad_s,
      static_cast<unsigned long long>(run.counters.accel_rejected));
}

}  // namespace
}  // namespace wallar::test
