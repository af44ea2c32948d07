// SPDX-License-Identifier: Apache-2.0
/// @file gyro_integration.hpp
/// @brief The rotation the gyro measured between two camera times: bias-corrected rates
/// integrated over the interval, on the IMU's clock shifted by the camera-IMU time offset.
///
/// Time: the interval is given in camera time; a sample stamped t_imu was taken at camera time
/// t_imu - timeshift_cam_imu_ns (Kalibr's convention: t_imu = t_cam + timeshift). Between two
/// samples the rate is their mean (midpoint rule); an interval end past the newest sample is
/// covered by holding its rate for at most `max_extrapolation_ns`.
///
/// Threading: pure functions; nothing allocates.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>

#include "wallar/core/imu_sample.hpp"
#include "wallar/core/time.hpp"

namespace wallar::dsp {

struct GyroDelta {
  /// R_imu(t0)_imu(t1): vectors of the IMU frame at t1 into the IMU frame at t0.
  Eigen::Quaterniond q_start_end = Eigen::Quaterniond::Identity();
  /// The specific force (accelerometer, bias subtracted) integrated once and twice over the
  /// interval, in the IMU frame at t0 (preintegration: gravity and the velocity at t0 are not
  /// in them). The IMU's displacement is v0 dt + g dt^2 / 2 + R_world_imu(t0) dp_m.
  Eigen::Vector3d dv_m_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d dp_m = Eigen::Vector3d::Zero();
  double covered_s = 0.0;  //!< the part of the interval the samples (and extrapolation) cover
  int samples = 0;         //!< samples that contributed
  /// The samples cover at least `min_coverage` of the interval.
  bool valid = false;
};

struct GyroIntegrationOptions {
  std::int64_t timeshift_cam_imu_ns = 0;  //!< t_imu = t_cam + this
  Eigen::Vector3d accel_bias_m_s2 = Eigen::Vector3d::Zero();
  DurationNs max_extrapolation_ns = 20 * kNsPerMs;
  double min_coverage = 0.8;
};

/// Integrates the samples of `older` then `newer` (one time-ordered sequence split in two, as a
/// ring buffer holds it) over camera times (t0_cam_ns, t1_cam_ns], subtracting `bias_rad_s`.
GyroDelta integrate_gyro(std::span<const ImuSample> older, std::span<const ImuSample> newer,
                         TimeNs t0_cam_ns, TimeNs t1_cam_ns, const Eigen::Vector3d& bias_rad_s,
                         const GyroIntegrationOptions& options = {});

}  // namespace wallar::dsp
