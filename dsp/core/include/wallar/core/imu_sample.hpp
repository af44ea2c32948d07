// SPDX-License-Identifier: Apache-2.0
/// @file imu_sample.hpp
/// @brief One inertial measurement, in the IMU (body) frame, SI units.
///
/// Threading: a plain value type; copy it freely between threads.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>

#include "wallar/core/time.hpp"

namespace wallar {

/// One IMU measurement. t_ns is when the sensor sampled it (data-ready edge, or the device
/// clock mapped to monotonic); publish_t_ns is when software handed it on (0 when unknown).
struct ImuSample {
  TimeNs t_ns = 0;                                       //!< sample time [ns]
  TimeNs publish_t_ns = 0;                               //!< publish time [ns], 0 = unknown
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();  //!< angular rate, body frame [rad/s]
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();  //!< specific force, body frame [m/s^2]
  std::optional<Eigen::Vector3d> mag_uT;                 //!< magnetic field, body frame [uT]
  std::optional<double> temperature_c;                   //!< die temperature [deg C]
  /// Attitude fused on the chip (BNO055), body vectors into the chip's own world frame.
  std::optional<Eigen::Quaterniond> q_chipworld_body;
};

}  // namespace wallar
