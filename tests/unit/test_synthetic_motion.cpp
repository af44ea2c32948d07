// SPDX-License-Identifier: Apache-2.0
/// @file test_synthetic_motion.cpp
/// @brief The synthetic moving headset (dsp/tracking/synthetic_motion.hpp) and its recording
/// (tools/eval/synth_rig.hpp): the IMU integrates back to the trajectory, the presets move as
/// asked (turn peaks, walking speed, repeating laps), the noise has the densities' statistics,
/// blur, rolling shutter and gain steps do what they model, the time offset shows between the IMU
/// and the ground truth, and the same seed writes the same bytes.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "wallar/drivers/config/yaml.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/tracking/synthetic_motion.hpp"
#include "wallar/eval/synth_rig.hpp"

namespace wallar::dsp {
namespace {

using test::TempDir;
namespace fs = std::filesystem;
constexpr double kRadPerDeg = M_PI / 180.0;

HeadMotionModel model_of(HeadMotion motion, std::uint64_t seed = 1, double peak = 300.0) {
  HeadMotionConfig c;
  c.motion = motion;
  c.seed = seed;
  c.peak_turn_deg_s = peak;
  c.duration_s = 30.0;
  return HeadMotionModel(headset_room(seed), c);
}

std::vector<SyntheticImuRow> perfect_imu(const HeadMotionModel& model, double rate_hz,
                                         double seconds) {
  SyntheticImuConfig c;
  c.rate_hz = rate_hz;  // noise and biases all zero
  SyntheticImu imu(model, c, 0, 0);
  std::vector<SyntheticImuRow> rows;
  while (imu.next_truth_t_ns() <= s_to_ns(seconds)) rows.push_back(imu.next());
  return rows;
}

double angle_between(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double a = w.norm();
  return a < 1e-15 ? Eigen::Matrix3d::Identity() : Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

constexpr std::array<HeadMotion, 4> kAll = {HeadMotion::kLookAround, HeadMotion::kWalk,
                                            HeadMotion::kQuickTurns, HeadMotion::kRoomLoop};

// The analytic derivatives against central differences of the pose itself (independent of the
// jets): velocity, acceleration and the body angular rate.
TEST(SyntheticMotion, DerivativesMatchFiniteDifferencesOfThePose) {
  for (const HeadMotion m : kAll) {
    const HeadMotionModel model = model_of(m);
    for (const double t : {0.3, 1.7, 2.4, 3.3, 5.05, 7.9, 12.2}) {
      const double h = 1e-4;
      const BodyMotionState s = model.state(t);
      const SE3d Tm = model.T_world_body(t - h), Tp = model.T_world_body(t + h);
      const Eigen::Vector3d v_fd = (Tp.translation() - Tm.translation()) / (2 * h);
      const Eigen::Vector3d a_fd =
          (Tp.translation() - 2 * s.T_world_body.translation() + Tm.translation()) / (h * h);
      EXPECT_LT((v_fd - s.vel_world_m_s).norm(), 1e-6) << to_string(m) << " t=" << t;
      EXPECT_LT((a_fd - s.accel_world_m_s2).norm(), 2e-3) << to_string(m) << " t=" << t;
      const Eigen::AngleAxisd d(Tm.linear().transpose() * Tp.linear());
      const Eigen::Vector3d w_fd = d.angle() * d.axis() / (2 * h);
      EXPECT_LT((w_fd - s.omega_body_rad_s).norm(), 1e-5) << to_string(m) << " t=" << t;
    }
  }
}

// Strapdown integration of a perfect IMU (1 kHz, midpoint rule) from the true initial state
// reproduces the trajectory: gyro = body rate, accel = R^T (a - g).
TEST(SyntheticMotion, ImuIntegratesBackToTheTrajectory) {
  for (const HeadMotion m : kAll) {
    const HeadMotionModel model = model_of(m);
    const std::vector<SyntheticImuRow> rows = perfect_imu(model, 1000.0, 8.0);
    const Eigen::Vector3d g(0.0, 0.0, -9.81);
    Eigen::Matrix3d R = rows[0].truth.T_world_body.linear();
    Eigen::Vector3d v = rows[0].truth.vel_world_m_s;
    Eigen::Vector3d p = rows[0].truth.T_world_body.translation();
    double worst_angle = 0.0, worst_pos = 0.0, worst_accel = 0.0;
    for (std::size_t k = 0; k + 1 < rows.size(); ++k) {
      const ImuSample& a = rows[k].sample;
      const ImuSample& b = rows[k + 1].sample;
      const double dt = ns_to_s(b.t_ns - a.t_ns);
      const Eigen::Matrix3d R_next = R * exp_so3(0.5 * (a.gyro_rad_s + b.gyro_rad_s) * dt);
      const Eigen::Vector3d acc_a = R * a.accel_m_s2 + g, acc_b = R_next * b.accel_m_s2 + g;
      p += v * dt + (acc_a / 3.0 + acc_b / 6.0) * dt * dt;
      v += 0.5 * (acc_a + acc_b) * dt;
      R = R_next;
      const BodyMotionState& truth = rows[k + 1].truth;
      // The accelerometer is the specific force of the truth, in the body frame.
      worst_accel = std::max(
          worst_accel,
          (truth.T_world_body.linear() * b.accel_m_s2 + g - truth.accel_world_m_s2).norm());
      if (k + 1 <= 4000) {  // position from double integration drifts: the first 4 s
        worst_pos = std::max(worst_pos, (p - truth.T_world_body.translation()).norm());
      }
      worst_angle = std::max(worst_angle, angle_between(R, truth.T_world_body.linear()));
    }
    EXPECT_LT(worst_accel, 1e-9) << to_string(m);
    EXPECT_LT(worst_angle, 0.02 * kRadPerDeg) << to_string(m) << ": gyro integration over 8 s";
    EXPECT_LT(worst_pos, 0.01) << to_string(m) << ": position over 4 s";
  }
}

TEST(SyntheticMotion, QuickTurnsPeakAtTheRequestedRate) {
  for (const double peak_deg_s : {300.0, 180.0}) {
    const HeadMotionModel model = model_of(HeadMotion::kQuickTurns, 3, peak_deg_s);
    ASSERT_GE(model.turns().size(), 5u);
    for (const QuickTurn& turn : model.turns()) {
      if (turn.t_start_s > 20.0) break;
      double peak = 0.0;
      for (double t = turn.t_start_s; t <= turn.t_start_s + turn.duration_s; t += 1e-3) {
        peak = std::max(peak, model.state(t).omega_body_rad_s.norm());
      }
      EXPECT_NEAR(peak / kRadPerDeg, peak_deg_s, 0.05 * peak_deg_s) << "turn at " << turn.t_start_s;
      EXPECT_GE(std::abs(turn.yaw_rad), 59.0 * kRadPerDeg);
    }
    // Between turns the head is nearly still: a turn is a distinct event.
    const QuickTurn& first = model.turns()[0];
    const QuickTurn& second = model.turns()[1];
    const double between = 0.5 * (first.t_start_s + first.duration_s + second.t_start_s);
    EXPECT_LT(model.state(between).omega_body_rad_s.norm(), 10.0 * kRadPerDeg);
    // The gyro sees the same peak (1 kHz samples).
    double gyro_peak = 0.0;
    for (const SyntheticImuRow& r : perfect_imu(model, 1000.0, 12.0)) {
      gyro_peak = std::max(gyro_peak, r.sample.gyro_rad_s.norm());
    }
    EXPECT_NEAR(gyro_peak / kRadPerDeg, peak_deg_s, 0.05 * peak_deg_s);
  }
}

TEST(SyntheticMotion, WalkingIsOneToOneAndAHalfMetresPerSecondInsideTheRoom) {
  for (const HeadMotion m : {HeadMotion::kWalk, HeadMotion::kRoomLoop}) {
    const HeadMotionModel model = model_of(m, 2);
    const SyntheticRoom& room = model.room();
    EXPECT_GE(room.x_max_m - room.x_min_m, 8.0);
    EXPECT_GE(room.y_max_m - room.y_min_m, 6.0);
    const double moving = model.config().still_start_s + model.config().ramp_s;
    double lo = 1e9, hi = 0.0, clearance = 1e9, sum = 0.0;
    int n = 0;
    for (double t = moving; t < 40.0; t += 0.01) {
      const BodyMotionState s = model.state(t);
      const double v = s.vel_world_m_s.head<2>().norm();
      lo = std::min(lo, v);
      hi = std::max(hi, v);
      sum += v;
      ++n;
      clearance =
          std::min(clearance, room.distance_to_nearest_surface(s.T_world_body.translation()));
    }
    EXPECT_GE(lo, 1.0) << to_string(m);
    EXPECT_LE(hi, 1.5) << to_string(m);
    EXPECT_NEAR(sum / n, model.config().walk_speed_m_s, 0.05) << to_string(m);
    EXPECT_GT(clearance, 0.8) << to_string(m) << ": the head keeps away from walls and ceiling";
    // It starts from standing still (an IMU still window) and has a head bob of a few cm.
    EXPECT_LT(model.state(0.5).vel_world_m_s.norm(), 1e-12);
    double z_lo = 1e9, z_hi = -1e9;
    for (double t = 10.0; t < 14.0; t += 0.01) {
      const double z = model.state(t).T_world_body.translation().z();
      z_lo = std::min(z_lo, z);
      z_hi = std::max(z_hi, z);
    }
    EXPECT_GT(z_hi - z_lo, 0.03);
    EXPECT_LT(z_hi - z_lo, 0.12);
  }
}

TEST(SyntheticMotion, RoomLoopLapsRepeat) {
  const HeadMotionModel model = model_of(HeadMotion::kRoomLoop, 4);
  const double lap = model.lap_period_s();
  ASSERT_GT(lap, 5.0);
  ASSERT_LT(lap, 20.0);
  for (const double t : {3.0, 4.2, 7.7}) {
    for (const int laps : {1, 5, 50}) {  // 50 laps: well past a 10-minute capacity run
      const SE3d a = model.T_world_body(t);
      const SE3d b = model.T_world_body(t + laps * lap);
      EXPECT_LT((a.translation() - b.translation()).norm(), 1e-6) << t << " + " << laps;
      EXPECT_LT(angle_between(a.linear(), b.linear()), 1e-6) << t << " + " << laps;
    }
  }
  // The walk preset does not repeat (its look-around is not tied to the lap).
  const HeadMotionModel walk = model_of(HeadMotion::kWalk, 4);
  EXPECT_GT(angle_between(walk.T_world_body(4.0).linear(),
                          walk.T_world_body(4.0 + walk.lap_period_s()).linear()),
            2.0 * kRadPerDeg);
}

// White noise with sigma = density * sqrt(rate) per axis, bias steps with sigma = random walk /
// sqrt(rate), both zero-mean and uncorrelated sample to sample.
TEST(SyntheticMotion, ImuNoiseHasTheDensitiesStatistics) {
  const HeadMotionModel model = model_of(HeadMotion::kLookAround);
  for (const double rate : {200.0, 1000.0}) {
    SyntheticImuConfig c;
    c.rate_hz = rate;
    c.noise = default_headset_rig().imu;
    c.seed = 9;
    draw_initial_biases(c, 9);
    SyntheticImu imu(model, c, 0, 0);
    const int n = 30000;
    std::vector<Eigen::Vector3d> gyro(n), accel(n), dbg(n - 1), dba(n - 1);
    std::vector<SyntheticImuRow> rows(n);
    for (int k = 0; k < n; ++k) rows[k] = imu.next();
    EXPECT_EQ(rows[0].gyro_bias_rad_s, c.gyro_bias0_rad_s);
    const Eigen::Vector3d g(0.0, 0.0, -9.81);
    for (int k = 0; k < n; ++k) {
      const SyntheticImuRow& r = rows[k];
      gyro[k] = r.sample.gyro_rad_s - r.truth.omega_body_rad_s - r.gyro_bias_rad_s;
      accel[k] = r.sample.accel_m_s2 -
                 r.truth.T_world_body.linear().transpose() * (r.truth.accel_world_m_s2 - g) -
                 r.accel_bias_m_s2;
      if (k > 0) {
        dbg[k - 1] = r.gyro_bias_rad_s - rows[k - 1].gyro_bias_rad_s;
        dba[k - 1] = r.accel_bias_m_s2 - rows[k - 1].accel_bias_m_s2;
      }
    }
    const auto check = [&](const std::vector<Eigen::Vector3d>& x, double sigma, const char* what) {
      for (int axis = 0; axis < 3; ++axis) {
        double sum = 0, sum2 = 0, lag1 = 0;
        for (std::size_t k = 0; k < x.size(); ++k) {
          sum += x[k][axis];
          sum2 += x[k][axis] * x[k][axis];
          if (k > 0) lag1 += x[k][axis] * x[k - 1][axis];
        }
        const double m = static_cast<double>(x.size());
        const double sd = std::sqrt(sum2 / m);
        EXPECT_NEAR(sd, sigma, 0.03 * sigma) << what << " axis " << axis << " at " << rate << " Hz";
        EXPECT_LT(std::abs(sum / m), 4.0 * sigma / std::sqrt(m)) << what << " mean";
        EXPECT_LT(std::abs(lag1 / sum2), 0.03) << what << " correlation";
      }
    };
    check(gyro, c.noise.gyro_noise_density * std::sqrt(rate), "gyro white noise");
    check(accel, c.noise.accel_noise_density * std::sqrt(rate), "accel white noise");
    check(dbg, c.noise.gyro_random_walk / std::sqrt(rate), "gyro bias step");
    check(dba, c.noise.accel_random_walk / std::sqrt(rate), "accel bias step");
  }
}

// Small images keep these fast; the rig scaled like synth_rig_headset does.
SyntheticCamera small_camera() {
  SyntheticCamera c = default_headset_rig().camera;
  c.width_px = 320;
  c.height_px = 240;
  c.f_px = 225.0;
  c.cx_px = 159.5;
  c.cy_px = 119.5;
  return c;
}

double gradient_energy(const std::vector<std::uint8_t>& img, int w, int h) {
  double e = 0.0;
  for (int v = 0; v < h; ++v) {
    for (int u = 1; u < w; ++u) {
      const double d = double(img[v * w + u]) - double(img[v * w + u - 1]);
      e += d * d;
    }
  }
  return e;
}

struct Frame {
  std::vector<std::uint8_t> left, right;
  FrameFormation info;
};

Frame form(const HeadMotionModel& model, const SyntheticCamera& cam, double t_s,
           const ImagingConfig& ic, double gain = 1.0, std::uint64_t index = 0) {
  const SE3d T_body_cam0 = default_headset_rig().T_body_cam0;
  Frame f;
  f.left.resize(static_cast<std::size_t>(cam.width_px * cam.height_px));
  f.right.resize(f.left.size());
  std::vector<float> scratch;
  f.info = form_stereo_frame(
      model.room(), cam, [&](double t) { return model.T_world_body(t) * T_body_cam0; }, t_s, gain,
      index, ic, f.left, f.right, scratch);
  return f;
}

// render_room_accumulate adds what render_room rounds; per-row poses that are all the same give
// the same image; adaptive supersampling departs from full supersampling in a few pixels.
TEST(SyntheticRoomSampling, AccumulateAdaptiveAndPerRowPoses) {
  const HeadMotionModel model = model_of(HeadMotion::kLookAround);
  const SE3d T = model.T_world_body(6.0) * default_headset_rig().T_body_cam0;
  SyntheticCamera cam = small_camera();
  const std::size_t n = static_cast<std::size_t>(cam.width_px * cam.height_px);
  const auto rounded = [](const std::vector<float>& acc) {
    std::vector<std::uint8_t> out(acc.size());
    for (std::size_t i = 0; i < acc.size(); ++i) {
      out[i] = static_cast<std::uint8_t>(std::clamp(double(acc[i]), 0.0, 255.0) + 0.5);
    }
    return out;
  };
  for (const int spa : {1, 2}) {
    cam.samples_per_axis = spa;
    std::vector<std::uint8_t> reference(n);
    render_room(model.room(), cam, T, 1, reference);
    std::vector<float> acc(n, 0.0f);
    render_room_accumulate(model.room(), cam, std::span<const SE3d>(&T, 1), 1, 1.0f, acc);
    const std::vector<std::uint8_t> once = rounded(acc);
    int off = 0;
    for (std::size_t i = 0; i < n; ++i) off += std::abs(int(once[i]) - int(reference[i])) > 1;
    EXPECT_EQ(off, 0) << "spa " << spa << ": accumulate is render_room before rounding";
    std::vector<float> rows(n, 0.0f);
    const std::vector<SE3d> same(static_cast<std::size_t>(cam.height_px), T);
    render_room_accumulate(model.room(), cam, same, 1, 1.0f, rows);
    EXPECT_EQ(rows, acc) << "one pose per row, all the same";
  }
  cam.samples_per_axis = 2;
  std::vector<std::uint8_t> full(n), adaptive(n);
  render_room(model.room(), cam, T, 0, full);
  cam.adaptive = true;
  render_room(model.room(), cam, T, 0, adaptive);
  int differ = 0, edges = 0;
  for (std::size_t i = 0; i < n; ++i) differ += full[i] != adaptive[i] ? 1 : 0;
  for (std::size_t i = 1; i < n; ++i) edges += std::abs(int(full[i]) - int(full[i - 1])) > 20;
  EXPECT_GT(edges, 1000) << "a textured view with many edges";
  EXPECT_LT(differ, static_cast<int>(n / 1000)) << "adaptive differs in " << differ << " pixels";
  std::vector<float> acc(n, 0.0f);
  const std::vector<SE3d> two(2, T);
  EXPECT_THROW(render_room_accumulate(model.room(), cam, two, 0, 1.0f, acc), std::invalid_argument);
}

TEST(SyntheticImaging, BlurLowersGradientEnergyOnAFastTurnOnly) {
  const HeadMotionModel model = model_of(HeadMotion::kQuickTurns);
  const QuickTurn& turn = model.turns().at(0);
  const double mid_turn = turn.t_start_s + 0.5 * turn.duration_s;
  const SyntheticCamera cam = small_camera();
  ImagingConfig sharp;
  sharp.blur = false;
  sharp.read_noise_dn = sharp.shot_noise_dn = 0.0;
  ImagingConfig blurred = sharp;
  blurred.blur = true;
  blurred.exposure_s = 0.008;
  const Frame a = form(model, cam, mid_turn, sharp);
  const Frame b = form(model, cam, mid_turn, blurred);
  // 300 deg/s for 8 ms at f = 225 px: 9.4 px of motion at the centre, up to 1.5x that at the
  // image's sides; a sub-frame per 2 px of it.
  const double centre_px = 300.0 * kRadPerDeg * 0.008 * 225.0;
  EXPECT_GT(b.info.motion_px, centre_px);
  EXPECT_LT(b.info.motion_px, 1.7 * centre_px);
  EXPECT_EQ(b.info.blur_samples, static_cast<int>(std::ceil(b.info.motion_px / 2.0)));
  EXPECT_LT(gradient_energy(b.left, cam.width_px, cam.height_px),
            0.5 * gradient_energy(a.left, cam.width_px, cam.height_px));
  // Standing still before the motion starts: blur on changes (almost) nothing.
  const Frame c = form(model, cam, 0.5, sharp);
  const Frame d = form(model, cam, 0.5, blurred);
  EXPECT_EQ(d.info.blur_samples, 1);
  EXPECT_GT(gradient_energy(d.left, cam.width_px, cam.height_px),
            0.95 * gradient_energy(c.left, cam.width_px, cam.height_px));
}

TEST(SyntheticImaging, RollingShutterRowsAreSeenAtTheirRowTimes) {
  const HeadMotionModel model = model_of(HeadMotion::kQuickTurns);
  const QuickTurn& turn = model.turns().at(0);
  const double t = turn.t_start_s + 0.5 * turn.duration_s;
  const SyntheticCamera cam = small_camera();
  ImagingConfig global;
  global.blur = false;
  global.read_noise_dn = global.shot_noise_dn = 0.0;
  global.still_samples_per_axis = 1;
  global.optics_blur = false;  // it mixes neighbouring rows, seen at other times
  ImagingConfig rolling = global;
  rolling.rolling_shutter_s = 0.02;
  const Frame rs = form(model, cam, t, rolling);
  const std::size_t w = static_cast<std::size_t>(cam.width_px);
  for (const int v : {0, 60, 119, 200, 239}) {
    const double tv = row_time_s(rolling, cam.height_px, t, v);
    const Frame g = form(model, cam, tv, global);
    EXPECT_TRUE(
        std::equal(rs.left.begin() + v * w, rs.left.begin() + (v + 1) * w, g.left.begin() + v * w))
        << "row " << v << " is the global-shutter image at its own time";
  }
  EXPECT_NEAR(row_time_s(rolling, cam.height_px, t, 0), t - 0.01, 1e-12);
  EXPECT_NEAR(row_time_s(rolling, cam.height_px, t, 239), t + 0.01, 1e-12);
  // At 300 deg/s the top rows have moved ~3 deg (12 px) against a global shutter at t.
  const Frame g = form(model, cam, t, global);
  int differ = 0;
  for (std::size_t i = 0; i < 10 * w; ++i) differ += rs.left[i] != g.left[i] ? 1 : 0;
  EXPECT_GT(differ, static_cast<int>(5 * w));
}

TEST(SyntheticImaging, GainStepsScaleTheMeanIntensityByTheStep) {
  const std::vector<double> gains = auto_exposure_gains(600, 20.0, true, 5);
  std::vector<std::size_t> steps;
  for (std::size_t k = 1; k < gains.size(); ++k) {
    if (gains[k] != gains[k - 1]) {
      steps.push_back(k);
      EXPECT_NEAR(std::max(gains[k] / gains[k - 1], gains[k - 1] / gains[k]), 1.25, 1e-12);
    }
    EXPECT_GE(gains[k], 1.0 / (1.25 * 1.25) - 1e-12);
    EXPECT_LE(gains[k], 1.25 * 1.25 + 1e-12);
  }
  // 30 s at one step per 2-5 s.
  EXPECT_GE(steps.size(), 6u);
  EXPECT_LE(steps.size(), 15u);
  for (std::size_t i = 1; i < steps.size(); ++i) EXPECT_GE(steps[i] - steps[i - 1], 40u);
  const std::vector<double> off = auto_exposure_gains(600, 20.0, false, 5);
  ASSERT_EQ(off.size(), 600u);
  EXPECT_TRUE(std::all_of(off.begin(), off.end(), [](double x) { return x == 1.0; }));

  // The same view at the gains either side of a step: the mean of the unclipped pixels moves
  // by the step (noise on: it is zero-mean).
  const HeadMotionModel model = model_of(HeadMotion::kLookAround);
  const SyntheticCamera cam = small_camera();
  const ImagingConfig ic;
  const std::size_t k = steps[0];
  const Frame before = form(model, cam, 4.0, ic, gains[k - 1], k - 1);
  const Frame after = form(model, cam, 4.0, ic, gains[k], k);
  double sum_before = 0, sum_after = 0;
  for (std::size_t i = 0; i < before.left.size(); ++i) {
    if (before.left[i] > 240 || after.left[i] > 240) continue;
    sum_before += before.left[i];
    sum_after += after.left[i];
  }
  EXPECT_NEAR(sum_after / sum_before, gains[k] / gains[k - 1], 0.01);
}

TEST(SyntheticImaging, PixelNoiseHasTheModelledSigma) {
  const HeadMotionModel model = model_of(HeadMotion::kLookAround);
  const SyntheticCamera cam = small_camera();
  ImagingConfig clean;
  clean.read_noise_dn = clean.shot_noise_dn = 0.0;
  ImagingConfig noisy;
  noisy.read_noise_dn = 6.0;
  noisy.shot_noise_dn = 0.1;
  const Frame a = form(model, cam, 0.5, clean);
  const Frame b = form(model, cam, 0.5, noisy, 1.0, 3);
  double sum2 = 0.0, sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < a.left.size(); ++i) {
    const double x = a.left[i];
    if (x < 40.0 || x > 200.0) continue;
    const double sigma = std::sqrt(36.0 + 0.1 * x);
    const double z = (double(b.left[i]) - x) / sigma;
    sum += z;
    sum2 += z * z;
    ++n;
  }
  ASSERT_GT(n, 30000);
  EXPECT_NEAR(std::sqrt(sum2 / n), 1.0, 0.05);
  EXPECT_NEAR(sum / n, 0.0, 0.03);
  // Counter-based: another frame gets other noise, the same frame the same.
  const Frame c = form(model, cam, 0.5, noisy, 1.0, 4);
  EXPECT_NE(b.left, c.left);
  EXPECT_EQ(b.left, form(model, cam, 0.5, noisy, 1.0, 3).left);
}

// ---------------------------------------------------------------------------------------------
// The recording

eval::SynthRigOptions small_options() {
  eval::SynthRigOptions o;
  o.motion = HeadMotion::kQuickTurns;
  o.duration_s = 4.0;
  o.width_px = 160;
  o.height_px = 120;
  o.imu_rate_hz = 1000.0;
  o.time_offset_ms = 7.0;
  o.rolling_shutter_ms = 10.0;
  o.gain_steps = true;
  o.seed = 11;
  return o;
}

std::map<std::string, std::string> files_under(const fs::path& root) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    if (e.is_regular_file()) files[fs::relative(e.path(), root).string()] = test::slurp(e.path());
  }
  return files;
}

TEST(SynthRigRecording, SameSeedWritesTheSameBytes) {
  TempDir tmp;
  const std::atomic<bool> stop{false};
  const eval::SynthRigOptions o = small_options();
  eval::write_synth_rig(o, tmp.path() / "a", stop);
  eval::write_synth_rig(o, tmp.path() / "b", stop);
  eval::SynthRigOptions other = o;
  other.seed = 12;
  eval::write_synth_rig(other, tmp.path() / "c", stop);
  const auto a = files_under(tmp.path() / "a");
  const auto b = files_under(tmp.path() / "b");
  const auto c = files_under(tmp.path() / "c");
  EXPECT_GT(a.size(), 2u * 80u + 10u);  // 80 PNGs per camera and the rest
  EXPECT_TRUE(a == b) << "same options and seed, different files";
  EXPECT_NE(a.at("mav0/cam0/data/1700000000000000000.png"),
            c.at("mav0/cam0/data/1700000000000000000.png"));
  EXPECT_NE(a.at("mav0/imu0/data.csv"), c.at("mav0/imu0/data.csv"));
  EXPECT_FALSE(fs::exists(tmp.path() / "a.part"));
}

TEST(SynthRigRecording, ReadsBackWithTheTimeOffsetBetweenImuAndGroundTruth) {
  TempDir tmp;
  const std::atomic<bool> stop{false};
  const eval::SynthRigOptions o = small_options();
  const nlohmann::json summary = eval::write_synth_rig(o, tmp.path() / "rec", stop);
  const recording::EurocRecording rec = recording::read_euroc(tmp.path() / "rec");
  ASSERT_EQ(rec.cams[0].frames.size(), 80u);
  ASSERT_EQ(rec.cams[1].frames.size(), 80u);
  EXPECT_EQ(rec.cams[0].frames[1].t_ns - rec.cams[0].frames[0].t_ns, 50'000'000);
  EXPECT_EQ(rec.cams[0].calib.width_px, 160);
  EXPECT_DOUBLE_EQ(rec.cams[0].calib.fx, 450.0 * 160 / 640);
  EXPECT_NEAR(rec.rig().T_cam0_cam1().translation().norm(), 0.10, 1e-12);
  // T_cam_imu: the axis permutation of a forward-looking camera, turned by a mounting error.
  Eigen::Matrix3d R_cam_imu_nominal;
  R_cam_imu_nominal << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  const double mounting = angle_between(rec.rig().T_cam0_imu().linear(), R_cam_imu_nominal);
  EXPECT_GT(mounting, 0.5 * kRadPerDeg);
  EXPECT_LT(mounting, 2.0 * kRadPerDeg);
  EXPECT_GT(rec.rig().T_cam0_imu().translation().norm(), 0.02);  // the IMU is cm from cam0
  EXPECT_DOUBLE_EQ(rec.imu_calib.rate_hz, 1000.0);
  EXPECT_DOUBLE_EQ(rec.imu_calib.gyro_noise_density, default_headset_rig().imu.gyro_noise_density);
  EXPECT_DOUBLE_EQ(rec.imu_calib.accel_random_walk, default_headset_rig().imu.accel_random_walk);
  const Image img =
      recording::load_png_gray(rec.cams[1].image_path(rec.cams[1].frames[30]), 160, 120);
  EXPECT_EQ(img.width(), 160);

  // Ground truth at the IMU's sample times; the IMU's stamps are 7 ms ahead of them.
  ASSERT_EQ(rec.ground_truth.size(), rec.imu.size());
  EXPECT_EQ(summary["imu_clock_offset_ns"].get<std::int64_t>(), 7'000'000);
  for (std::size_t i = 0; i < rec.imu.size(); ++i) {
    ASSERT_EQ(rec.imu[i].t_ns - rec.ground_truth[i].t_ns, 7'000'000) << i;
  }
  // The IMU spans the frames (and starts 0.5 s before them, still).
  EXPECT_LE(rec.ground_truth.front().t_ns, rec.cams[0].frames.front().t_ns - 400'000'000);
  EXPECT_GE(rec.ground_truth.back().t_ns, rec.cams[0].frames.back().t_ns);
  // And the offset is in the data, not only the stamps: the gyro's magnitude matches the truth's
  // angular rate best when shifted by 7 samples (7 ms at 1 kHz).
  std::vector<double> gyro, truth;
  for (std::size_t i = 0; i < rec.imu.size(); ++i) gyro.push_back(rec.imu[i].gyro_rad_s.norm());
  for (std::size_t i = 1; i + 1 < rec.ground_truth.size(); ++i) {
    const Eigen::AngleAxisd d(rec.ground_truth[i - 1].T_world_body.linear().transpose() *
                              rec.ground_truth[i + 1].T_world_body.linear());
    truth.push_back(d.angle() / 2e-3);
  }
  // truth[i] is at ground_truth[i + 1]; compare with the IMU row stamped that time + lag.
  int best_lag = -100;
  double best = 1e18;
  for (int lag = -20; lag <= 20; ++lag) {
    double err = 0.0;
    for (std::size_t i = 30; i + 30 < truth.size(); ++i) {
      // The IMU row whose stamp is ground_truth[i + 1].t_ns + lag ms.
      const std::ptrdiff_t j = static_cast<std::ptrdiff_t>(i + 1) + lag - 7;
      const double e = gyro[static_cast<std::size_t>(j)] - truth[i];
      err += e * e;
    }
    if (err < best) {
      best = err;
      best_lag = lag;
    }
  }
  EXPECT_EQ(best_lag, 7) << "the IMU's clock is 7 ms ahead of the ground truth's";

  // Where a calibration carries it, and in the ground truth's own files.
  const auto camchain =
      config::YamlDocument::load_file(tmp.path() / "rec" / "mav0" / "camchain-imucam.yaml");
  EXPECT_DOUBLE_EQ(camchain.root().at("cam0").at("timeshift_cam_imu").as_double(), 0.007);
  EXPECT_DOUBLE_EQ(camchain.root().at("cam1").at("timeshift_cam_imu").as_double(), 0.007);
  const Eigen::MatrixXd T_cam_imu = camchain.root().at("cam0").at("T_cam_imu").as_matrix(4, 4);
  EXPECT_LT((T_cam_imu - rec.rig().T_cam0_imu().matrix()).cwiseAbs().maxCoeff(), 1e-12);
  const fs::path gt_dir = tmp.path() / "rec" / "mav0" / "state_groundtruth_estimate0";
  const auto gt_yaml = config::YamlDocument::load_file(gt_dir / "sensor.yaml");
  EXPECT_EQ(gt_yaml.root().at("imu_clock_offset_ns").as_double(), 7e6);
  EXPECT_EQ(gt_yaml.root().get_string("motion", ""), "quick-turns");
  EXPECT_NE(test::slurp(gt_dir / "README.md").find("7000000 ns ahead"), std::string::npos);
  // camera_frames.csv: one row per frame with the gain that frame got.
  const std::string frames_csv = test::slurp(gt_dir / "camera_frames.csv");
  EXPECT_EQ(std::count(frames_csv.begin(), frames_csv.end(), '\n'), 81);
}

TEST(SynthRigRecording, GroundTruthAtCameraRateAndBadOptions) {
  TempDir tmp;
  const std::atomic<bool> stop{false};
  eval::SynthRigOptions o = small_options();
  o.ground_truth_at_camera_rate = true;
  o.duration_s = 1.0;
  eval::write_synth_rig(o, tmp.path() / "cam_rate", stop);
  const recording::EurocRecording rec = recording::read_euroc(tmp.path() / "cam_rate");
  ASSERT_EQ(rec.ground_truth.size(), rec.cams[0].frames.size());
  for (std::size_t i = 0; i < rec.ground_truth.size(); ++i) {
    EXPECT_EQ(rec.ground_truth[i].t_ns, rec.cams[0].frames[i].t_ns);
  }
  // The row round trip: what format_ground_truth_row writes, parse reads back exactly.
  const std::string text = std::string(recording::ground_truth_csv_header()) +
                           recording::format_ground_truth_row(rec.ground_truth[3]);
  const auto back = recording::parse_ground_truth_csv(text, "row");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].T_world_body.translation(), rec.ground_truth[3].T_world_body.translation());
  EXPECT_EQ(back[0].vel_world_m_s, rec.ground_truth[3].vel_world_m_s);

  const auto rejects = [&](auto edit, const std::string& option) {
    eval::SynthRigOptions bad = small_options();
    edit(bad);
    try {
      eval::check_synth_rig_options(bad);
      ADD_FAILURE() << option << " accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(option + ": ", 0), 0u) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  };
  rejects([](auto& b) { b.imu_rate_hz = 100.0; }, "--imu-rate");
  rejects([](auto& b) { b.imu_rate_hz = 2000.0; }, "--imu-rate");
  rejects([](auto& b) { b.exposure_ms = 60.0; }, "--blur");
  rejects([](auto& b) { b.rolling_shutter_ms = -1.0; }, "--rolling-shutter");
  rejects([](auto& b) { b.duration_s = 0.0; }, "--duration");
  rejects([](auto& b) { b.camera_rate_hz = 500.0; }, "--camera-rate");
  rejects([](auto& b) { b.noise_sigma = -1.0; }, "--noise");
  rejects([](auto& b) { b.peak_turn_deg_s = 5000.0; }, "--peak-turn-deg-s");
  rejects([](auto& b) { b.width_px = 10; }, "--width");
  rejects([](auto& b) { b.time_offset_ms = 5000.0; }, "--time-offset-ms");
  // An existing, non-empty output is left alone.
  fs::create_directories(tmp.path() / "full");
  test::spit(tmp.path() / "full" / "keep.txt", "mine");
  EXPECT_THROW(eval::write_synth_rig(small_options(), tmp.path() / "full", stop), InputError);
  EXPECT_EQ(test::slurp(tmp.path() / "full" / "keep.txt"), "mine");
  EXPECT_FALSE(fs::exists(tmp.path() / "full.part"));
  // Interrupted: nothing left behind.
  const std::atomic<bool> stopped{true};
  const nlohmann::json j = eval::write_synth_rig(small_options(), tmp.path() / "stopped", stopped);
  EXPECT_TRUE(j.value("interrupted", false));
  EXPECT_FALSE(fs::exists(tmp.path() / "stopped"));
  EXPECT_FALSE(fs::exists(tmp.path() / "stopped.part"));
}

}  // namespace
}  // namespace wallar::dsp
