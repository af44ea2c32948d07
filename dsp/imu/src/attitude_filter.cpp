// SPDX-License-Identifier: Apache-2.0
/// @file attitude_filter.cpp
/// @brief Error-state Kalman filter of attitude and gyro bias.
#include "wallar/dsp/imu/attitude_filter.hpp"

#include <algorithm>
#include <cmath>

namespace wallar::dsp {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

// Exp of a rotation vector as a unit quaternion (exact; first order near zero).
Eigen::Quaterniond exp_q(const Eigen::Vector3d& rotvec_rad) {
  const double angle = rotvec_rad.norm();
  if (angle < 1e-12) {
    return Eigen::Quaterniond(1.0, 0.5 * rotvec_rad.x(), 0.5 * rotvec_rad.y(), 0.5 * rotvec_rad.z())
        .normalized();
  }
  const double s = std::sin(0.5 * angle) / angle;
  return Eigen::Quaterniond(std::cos(0.5 * angle), s * rotvec_rad.x(), s * rotvec_rad.y(),
                            s * rotvec_rad.z());
}

double wrap_pi(double a) { return std::remainder(a, 2.0 * M_PI); }

}  // namespace

AttitudeFilter::AttitudeFilter(const AttitudeFilterConfig& config) : config_(config) {
  config_.init_window_samples = std::max<std::size_t>(config_.init_window_samples, 2);
  window_.reserve(config_.init_window_samples);
}

void AttitudeFilter::initialize(const StaticImuEstimate& still, TimeNs t_ns) {
  init_ = still;
  initialized_ = true;
  t_ns_ = t_ns;
  q_world_imu_ = still.q_world_body.normalized();
  gyro_bias_rad_s_ = still.gyro_bias_rad_s;
  last_gyro_rad_s_ = still.gyro_bias_rad_s;
  const double g = still.mean_accel_m_s2.norm();
  gravity_m_s2_ = g > 1.0 ? g : 9.81;
  P_.setZero();
  P_.topLeftCorner<3, 3>().diagonal().setConstant(config_.initial_tilt_std_rad *
                                                  config_.initial_tilt_std_rad);
  P_.bottomRightCorner<3, 3>().diagonal().setConstant(config_.initial_bias_std_rad_s *
                                                      config_.initial_bias_std_rad_s);
  have_mag_ref_ = false;
  window_.clear();
}

bool AttitudeFilter::update(const ImuSample& raw) {
  ++counters_.samples;
  // The calibration's accelerometer bias and magnetometer iron, before anything uses them.
  ImuSample sample = raw;
  sample.accel_m_s2 -= config_.accel_bias_m_s2;
  if (sample.mag_uT)
    *sample.mag_uT = config_.mag_soft_iron * (*sample.mag_uT - config_.mag_hard_iron_uT);
  if (!sample.gyro_rad_s.allFinite() || !sample.accel_m_s2.allFinite()) {
    ++counters_.bad_samples;
    return initialized_;
  }
  if (!initialized_) {
    if (!window_.empty() && sample.t_ns <= window_.back().t_ns) {
      ++counters_.bad_samples;
      return false;
    }
    window_.push_back(sample);  // never beyond the reserved capacity: no allocation
    if (window_.size() < config_.init_window_samples) return false;
    const auto est = estimate_static_imu(window_, window_.front().t_ns, window_.back().t_ns,
                                         config_.init_window_samples);
    if (est && is_still(*est, config_.stillness)) {
      initialize(*est, sample.t_ns);
      last_gyro_rad_s_ = sample.gyro_rad_s;
      return true;
    }
    ++counters_.init_windows_rejected;
    // Slide by half a window and try again when it is full.
    const auto half = static_cast<std::ptrdiff_t>(window_.size() / 2);
    window_.erase(window_.begin(), window_.begin() + half);
    return false;
  }
  if (sample.t_ns <= t_ns_) {
    ++counters_.bad_samples;
    return true;
  }
  const DurationNs dt_ns = sample.t_ns - t_ns_;
  if (dt_ns > config_.max_dt_ns) {
    ++counters_.gaps;
  } else {
    // The rate over the interval: the mean of its two end samples.
    propagate(0.5 * (last_gyro_rad_s_ + sample.gyro_rad_s), ns_to_s(dt_ns));
  }
  t_ns_ = sample.t_ns;
  last_gyro_rad_s_ = sample.gyro_rad_s;
  update_accel(sample.accel_m_s2);
  if (sample.mag_uT && sample.mag_uT->allFinite()) update_mag(*sample.mag_uT);
  return true;
}

void AttitudeFilter::propagate(const Eigen::Vector3d& gyro_rad_s, double dt_s) {
  const Eigen::Vector3d rotvec = (gyro_rad_s - gyro_bias_rad_s_) * dt_s;
  const Eigen::Quaterniond dq = exp_q(rotvec);
  q_world_imu_ = (q_world_imu_ * dq).normalized();
  // Error dynamics: dtheta' = -[w]x dtheta - dbias, dbias' = noise. Discretised over dt with
  // the exact rotation of the error and a first-order bias coupling.
  const Eigen::Matrix3d A = dq.toRotationMatrix().transpose();
  const Eigen::Matrix3d P_tt = P_.topLeftCorner<3, 3>();
  const Eigen::Matrix3d P_tb = P_.topRightCorner<3, 3>();
  const Eigen::Matrix3d P_bb = P_.bottomRightCorner<3, 3>();
  const Eigen::Matrix3d AP_tb = A * P_tb;
  const double qg = config_.gyro_noise_rad_s_sqrt_hz * config_.gyro_noise_rad_s_sqrt_hz * dt_s;
  const double qb =
      config_.gyro_bias_walk_rad_s2_sqrt_hz * config_.gyro_bias_walk_rad_s2_sqrt_hz * dt_s;
  Eigen::Matrix3d new_tt =
      A * P_tt * A.transpose() - dt_s * (AP_tb + AP_tb.transpose()) + (dt_s * dt_s) * P_bb;
  new_tt.diagonal().array() += qg;
  const Eigen::Matrix3d new_tb = AP_tb - dt_s * P_bb;
  P_.topLeftCorner<3, 3>() = new_tt;
  P_.topRightCorner<3, 3>() = new_tb;
  P_.bottomLeftCorner<3, 3>() = new_tb.transpose();
  P_.bottomRightCorner<3, 3>().diagonal().array() += qb;
}

void AttitudeFilter::correct(const Eigen::Matrix<double, 6, 1>& dx) {
  q_world_imu_ = (q_world_imu_ * exp_q(dx.head<3>())).normalized();
  gyro_bias_rad_s_ += dx.tail<3>();
}

void AttitudeFilter::update_accel(const Eigen::Vector3d& accel_m_s2) {
  const double norm = accel_m_s2.norm();
  const double excess = std::abs(norm - gravity_m_s2_);
  if (!(excess <= config_.accel_reject_m_s2)) {
    ++counters_.accel_rejected;
    return;
  }
  ++counters_.accel_updates;
  const double motion_m_s2 = config_.accel_noise_m_s2 + config_.accel_noise_per_excess * excess;
  const double sigma = std::hypot(config_.accel_sensor_noise_m_s2, motion_m_s2) / gravity_m_s2_;
  // z = a/|a| is "up" in the IMU frame: z = Exp(-dtheta) u ~ u + [u]x dtheta.
  const Eigen::Vector3d up_imu = q_world_imu_.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d residual = accel_m_s2 / norm - up_imu;
  const Eigen::Matrix3d H_t = skew(up_imu);
  const Eigen::Matrix<double, 6, 3> PHt = P_.leftCols<3>() * H_t.transpose();
  Eigen::Matrix3d S = H_t * PHt.topRows<3>();
  S.diagonal().array() += sigma * sigma;
  const Eigen::Matrix<double, 6, 3> K = PHt * S.inverse();
  correct(K * residual);
  // P = (I - K H) P with H = [H_t 0]; symmetrised against round-off.
  P_ -= K * (H_t * P_.topRows<3>());
  P_ = 0.5 * (P_ + P_.transpose()).eval();
}

void AttitudeFilter::update_mag(const Eigen::Vector3d& mag_uT) {
  const Eigen::Vector3d mag_world = q_world_imu_ * mag_uT;
  const double horizontal = mag_world.head<2>().norm();
  if (!(horizontal > 0.1 * mag_world.norm())) return;  // near a magnetic pole: no heading
  const double heading = std::atan2(mag_world.y(), mag_world.x());
  const double norm = mag_world.norm();
  const double inclination = std::asin(std::clamp(mag_world.z() / norm, -1.0, 1.0));
  if (!have_mag_ref_) {  // the world's heading is defined by the first field seen
    have_mag_ref_ = true;
    mag_heading_ref_rad_ = heading;
    mag_norm_ref_uT_ = norm;
    mag_inclination_ref_rad_ = inclination;
    return;
  }
  // The earth's field has one strength and one dip: a reading that disagrees is no heading (an
  // uncalibrated magnetometer's hard iron turning with the head, a nearby magnet or motor).
  if (std::abs(norm / mag_norm_ref_uT_ - 1.0) > config_.mag_norm_tolerance ||
      std::abs(inclination - mag_inclination_ref_rad_) > config_.mag_inclination_tolerance_rad) {
    ++counters_.mag_rejected;
    return;
  }
  // The true heading is heading + e_z . (R dtheta): a yaw-only measurement.
  const Eigen::Matrix<double, 1, 3> H_t =
      Eigen::Vector3d::UnitZ().transpose() * q_world_imu_.toRotationMatrix();
  const Eigen::Matrix<double, 6, 1> PHt = P_.leftCols<3>() * H_t.transpose();
  const double S =
      H_t * PHt.head<3>() + config_.mag_heading_noise_rad * config_.mag_heading_noise_rad;
  const double innovation = wrap_pi(mag_heading_ref_rad_ - heading);
  // Beyond the gate the linear update is no longer valid, and it would tilt the estimate.
  if (innovation * innovation > config_.mag_gate_sigma * config_.mag_gate_sigma * S) {
    ++counters_.mag_rejected;
    return;
  }
  ++counters_.mag_updates;
  const Eigen::Matrix<double, 6, 1> K = PHt / S;
  correct(K * innovation);
  P_ -= K * (H_t * P_.topRows<3>());
  P_ = 0.5 * (P_ + P_.transpose()).eval();
}

double AttitudeFilter::tilt_std_rad() const {
  const Eigen::Matrix3d R = q_world_imu_.toRotationMatrix();
  const Eigen::Matrix3d P_world = R * P_.topLeftCorner<3, 3>() * R.transpose();
  return std::sqrt(std::max(P_world(0, 0), P_world(1, 1)));
}

double tilt_error_rad(const Eigen::Quaterniond& q_world_imu_a,
                      const Eigen::Quaterniond& q_world_imu_b) {
  const Eigen::Vector3d up_a = q_world_imu_a.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_b = q_world_imu_b.conjugate() * Eigen::Vector3d::UnitZ();
  return std::atan2(up_a.cross(up_b).norm(), up_a.dot(up_b));
}

}  // namespace wallar::dsp
