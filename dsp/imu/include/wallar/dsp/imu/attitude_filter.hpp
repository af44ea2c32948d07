// SPDX-License-Identifier: Apache-2.0
/// @file attitude_filter.hpp
/// @brief Attitude and gyro bias from gyro + accelerometer (+ optional magnetometer): an
/// error-state Kalman filter, initialised from the first still window.
///
/// State: q_world_imu (IMU vectors into a gravity-aligned world frame, z up, yaw free) and
/// gyro_bias_rad_s. Error state (6): a rotation error dtheta in the IMU frame
/// (q_true = q_est * Exp(dtheta)) and a bias error. Propagation integrates the bias-corrected
/// gyro; the accelerometer's direction is a measurement of "up" in the IMU frame, with a noise
/// that grows as |a| departs from g (the vehicle accelerates) and is skipped beyond a limit;
/// a magnetometer, when a sample carries one, corrects the heading only (so a disturbed field
/// never tilts the estimate), and only while its strength and dip are the first reading's and
/// its heading is within a gate of the prediction (an uncalibrated or disturbed one is refused,
/// counted). Gyro bias about the vertical axis is only observable from the
/// magnetometer or from turns; without either it stays at its still-window value.
///
/// Initialisation: samples are collected in a window of a fixed number of samples; when
/// estimate_static_imu() says the window is still, gravity and gyro bias are taken from it.
/// A moving window is slid by half and retried.
///
/// Threading: one instance per thread; update() is called with increasing t_ns. Nothing is
/// allocated after construction (update() is fixed-rate code).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "wallar/core/imu_sample.hpp"
#include "wallar/dsp/imu/static_init.hpp"

namespace wallar::dsp {

/// Defaults tuned on EuRoC V1_01 (a multicopter, ADIS16448 at 200 Hz; docs/results.md): the
/// filter trusts the gyro over short times and the accelerometer only on average, because a
/// flying body's accelerometer sees its accelerations as well as gravity.
struct AttitudeFilterConfig {
  /// Gyro white noise as the filter sees it (ADIS16448 datasheet: 1.7e-4). Larger values trust
  /// the accelerometer more and, on EuRoC, raise the tilt error (2e-3: 0.92 degrees RMS).
  double gyro_noise_rad_s_sqrt_hz = 3.0e-4;
  double gyro_bias_walk_rad_s2_sqrt_hz = 2.0e-5;  //!< gyro bias random walk (datasheet 1.9e-5)
  /// The accelerometer's own white noise per sample [m/s^2]: its noise density times the root
  /// of its rate, from the IMU's calibration (`wallar calibrate imu-noise`, a datasheet's);
  /// 0: none known. Added (root sum of squares) to the motion term below.
  double accel_sensor_noise_m_s2 = 0.0;
  /// What moves the accelerometer off gravity besides its own noise, when |a| = g: vibration
  /// and the accelerations a body always has [m/s^2]; a model of the motion, not of the sensor
  /// (0.5 gives 0.82 degrees RMS on EuRoC, 6 gives 0.98).
  double accel_noise_m_s2 = 1.5;
  /// Added to the accelerometer noise per m/s^2 that |a| departs from g: the vehicle is
  /// accelerating and the accelerometer no longer points up.
  double accel_noise_per_excess = 4.0;
  /// Beyond this departure of |a| from g the accelerometer is not used at all [m/s^2].
  double accel_reject_m_s2 = 3.0;
  double mag_heading_noise_rad = 0.05;  //!< heading noise of the magnetometer
  /// A reading whose strength differs from the first one's by more than this fraction, or
  /// whose dip by more than this angle, is not used (not the earth's field alone).
  double mag_norm_tolerance = 0.1;
  double mag_inclination_tolerance_rad = 0.1;
  /// A heading innovation beyond this many of its standard deviations is not used.
  double mag_gate_sigma = 4.0;
  /// Subtracted from every accelerometer sample (the calibration's, `wallar calibrate
  /// accel-mag`) [m/s^2]: a bias tilts the still window's gravity by |b| / g.
  Eigen::Vector3d accel_bias_m_s2 = Eigen::Vector3d::Zero();
  /// The magnetometer is used as soft_iron * (m - hard_iron) (the calibration's).
  Eigen::Vector3d mag_hard_iron_uT = Eigen::Vector3d::Zero();
  Eigen::Matrix3d mag_soft_iron = Eigen::Matrix3d::Identity();
  double initial_tilt_std_rad = 0.01;      //!< trust in the still window's gravity
  double initial_bias_std_rad_s = 2.0e-3;  //!< trust in the still window's gyro bias
  std::size_t init_window_samples = 200;   //!< still window: 1 s at 200 Hz
  StillnessLimits stillness;
  /// A gap between samples longer than this is not integrated (the gyro is unknown) [ns].
  DurationNs max_dt_ns = 100 * kNsPerMs;
};

/// Counters of what update() did, for reports and tests.
struct AttitudeFilterCounters {
  std::uint64_t samples = 0;                //!< every call to update()
  std::uint64_t init_windows_rejected = 0;  //!< windows not still enough
  std::uint64_t accel_updates = 0;
  std::uint64_t accel_rejected = 0;  //!< |a| too far from g
  std::uint64_t mag_updates = 0;
  std::uint64_t mag_rejected = 0;  //!< strength, dip or heading not the reference field's
  std::uint64_t gaps = 0;          //!< dt > max_dt_ns: propagation skipped
  std::uint64_t bad_samples = 0;   //!< non-finite or time not increasing: ignored
};

class AttitudeFilter {
 public:
  /// Allocates the still-window buffer (the only allocation).
  explicit AttitudeFilter(const AttitudeFilterConfig& config = {});

  /// Starts from a known still estimate (gravity, gyro bias) at t_ns, skipping the window.
  void initialize(const StaticImuEstimate& still, TimeNs t_ns);

  /// Feeds one sample, corrected by the config's accelerometer bias and magnetometer iron.
  /// Returns true when the filter is initialised after it (the state is meaningful). Before
  /// that the sample goes into the still window.
  bool update(const ImuSample& sample);

  [[nodiscard]] bool initialized() const { return initialized_; }
  /// The still window the filter started from (valid once initialized()).
  [[nodiscard]] const StaticImuEstimate& initial_estimate() const { return init_; }
  [[nodiscard]] TimeNs t_ns() const { return t_ns_; }

  [[nodiscard]] const Eigen::Quaterniond& q_world_imu() const { return q_world_imu_; }
  [[nodiscard]] const Eigen::Vector3d& gyro_bias_rad_s() const { return gyro_bias_rad_s_; }
  /// Unit gravity ("down") in the IMU frame.
  [[nodiscard]] Eigen::Vector3d gravity_dir_imu() const {
    return q_world_imu_.conjugate() * Eigen::Vector3d(0.0, 0.0, -1.0);
  }
  /// Unit gravity in another sensor's frame, e.g. the left camera: R_cam_imu takes IMU vectors
  /// into that frame (RigCalibration::T_cam0_imu().linear()).
  [[nodiscard]] Eigen::Vector3d gravity_dir_in(const Eigen::Matrix3d& R_sensor_imu) const {
    return R_sensor_imu * gravity_dir_imu();
  }
  /// 1-sigma uncertainty of the tilt (largest of the two horizontal axes) [rad].
  [[nodiscard]] double tilt_std_rad() const;
  /// 1-sigma uncertainty of the gyro bias per axis [rad/s].
  [[nodiscard]] Eigen::Vector3d gyro_bias_std_rad_s() const {
    return P_.diagonal().tail<3>().cwiseSqrt();
  }
  [[nodiscard]] const AttitudeFilterCounters& counters() const { return counters_; }
  [[nodiscard]] const AttitudeFilterConfig& config() const { return config_; }

 private:
  using Matrix6d = Eigen::Matrix<double, 6, 6>;
  void propagate(const Eigen::Vector3d& gyro_rad_s, double dt_s);
  void update_accel(const Eigen::Vector3d& accel_m_s2);
  void update_mag(const Eigen::Vector3d& mag_uT);
  void correct(const Eigen::Matrix<double, 6, 1>& dx);

  AttitudeFilterConfig config_;
  std::vector<ImuSample> window_;  //!< capacity init_window_samples, reserved at construction
  StaticImuEstimate init_;
  bool initialized_ = false;
  TimeNs t_ns_ = 0;
  Eigen::Vector3d last_gyro_rad_s_ = Eigen::Vector3d::Zero();
  double gravity_m_s2_ = 9.81;  //!< |a| of the still window: the accelerometer's own scale
  Eigen::Quaterniond q_world_imu_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d gyro_bias_rad_s_ = Eigen::Vector3d::Zero();
  Matrix6d P_ = Matrix6d::Zero();
  bool have_mag_ref_ = false;
  double mag_heading_ref_rad_ = 0.0;      //!< world heading of the field at the first mag sample
  double mag_norm_ref_uT_ = 0.0;          //!< its strength
  double mag_inclination_ref_rad_ = 0.0;  //!< its dip below the horizon (negative: down)
  AttitudeFilterCounters counters_;
};

/// Roll-pitch (tilt) difference between two attitudes, ignoring yaw: the angle between the
/// world "up" seen in the IMU frame by each [rad].
double tilt_error_rad(const Eigen::Quaterniond& q_world_imu_a,
                      const Eigen::Quaterniond& q_world_imu_b);

}  // namespace wallar::dsp
