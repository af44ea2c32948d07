// SPDX-License-Identifier: Apache-2.0
/// @file static_init.hpp
/// @brief Gravity direction and gyro bias from a window of IMU samples taken at rest.
///
/// At rest the accelerometer measures the reaction to gravity (+g up, in the body frame) and
/// the gyro measures its bias. The estimate also says how still the window was, so callers
/// can refuse a window in which the device moved.
///
/// Threading: pure functions; no state.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <span>

#include "wallar/core/imu_sample.hpp"

namespace wallar::dsp {

struct StaticImuEstimate {
  std::size_t samples = 0;
  TimeNs t_begin_ns = 0;
  TimeNs t_end_ns = 0;
  Eigen::Vector3d mean_accel_m_s2 = Eigen::Vector3d::Zero();  //!< body frame, "up" at rest
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();  //!< mean gyro, body frame
  double accel_std_m_s2 = 0.0;  //!< RMS deviation of |accel| from its mean
  double gyro_std_rad_s = 0.0;  //!< RMS deviation of the gyro from its mean (norm)
  /// Rotation that takes body vectors into a gravity-aligned world frame (z up), with the
  /// yaw left free (chosen so the body x axis keeps its heading where possible).
  Eigen::Quaterniond q_world_body = Eigen::Quaterniond::Identity();

  /// Unit vector of gravity ("down") in the body frame.
  [[nodiscard]] Eigen::Vector3d gravity_dir_body() const { return -mean_accel_m_s2.normalized(); }
};

/// What "at rest" allows: a device on a table or a multicopter on the ground with idling
/// motors vibrates (EuRoC V1_01: 0.26 m/s^2 and 0.067 rad/s RMS) but does not turn or move;
/// a head in motion exceeds these several times over.
struct StillnessLimits {
  double max_accel_std_m_s2 = 0.5;
  double max_gyro_std_rad_s = 0.1;
};

/// Estimates gravity and gyro bias from the samples with t in [t_begin_ns, t_end_ns], the
/// accelerometer's readings less `accel_bias_m_s2` (a calibration's, ImuCalibration).
/// Returns nothing when the window holds fewer than `min_samples`.
std::optional<StaticImuEstimate> estimate_static_imu(
    std::span<const ImuSample> samples, TimeNs t_begin_ns, TimeNs t_end_ns,
    std::size_t min_samples = 20, const Eigen::Vector3d& accel_bias_m_s2 = Eigen::Vector3d::Zero());

/// True when the estimate's spread is within the limits (the device was at rest).
bool is_still(const StaticImuEstimate& estimate, const StillnessLimits& limits = {});

}  // namespace wallar::dsp
