// SPDX-License-Identifier: Apache-2.0
/// @file calibration.hpp
/// @brief Sensor calibration as plain data: pinhole + radial-tangential cameras, IMU noise,
/// and the extrinsics T_body_sensor (body = IMU frame, EuRoC's convention).
///
/// Threading: value types.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "wallar/core/pose.hpp"

namespace wallar {

struct CameraCalibration {
  std::string name = "cam0";
  int width_px = 0;
  int height_px = 0;
  double rate_hz = 0.0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  //!< [px]
  std::string distortion_model = "radial-tangential";
  std::vector<double> distortion;  //!< k1, k2, p1, p2 for radial-tangential
  SE3d T_body_cam = SE3d::Identity();
};

struct ImuCalibration {
  double rate_hz = 0.0;
  double gyro_noise_density = 0.0;   //!< [rad/s/sqrt(Hz)]
  double gyro_random_walk = 0.0;     //!< [rad/s^2/sqrt(Hz)]
  double accel_noise_density = 0.0;  //!< [m/s^2/sqrt(Hz)]
  double accel_random_walk = 0.0;    //!< [m/s^3/sqrt(Hz)]
  /// Camera-IMU time offset: a sample stamped t_imu was taken at camera time t_imu - this
  /// (Kalibr's timeshift_cam_imu: t_imu = t_cam + shift) [ns].
  std::int64_t timeshift_cam_imu_ns = 0;
  SE3d T_body_imu = SE3d::Identity();
  /// Accelerometer bias, subtracted from every accelerometer sample before use (`wallar
  /// calibrate accel-mag`, from still poses in several tilts) [m/s^2].
  Eigen::Vector3d accel_bias_m_s2 = Eigen::Vector3d::Zero();
  /// Magnetometer hard and soft iron: the field is mag_soft_iron * (m - mag_hard_iron_uT)
  /// (`wallar calibrate accel-mag`, an ellipsoid fit over a turning recording). Zero and
  /// identity: uncorrected.
  Eigen::Vector3d mag_hard_iron_uT = Eigen::Vector3d::Zero();
  Eigen::Matrix3d mag_soft_iron = Eigen::Matrix3d::Identity();

  /// True when the file gave an accelerometer bias or a magnetometer correction.
  [[nodiscard]] bool has_accel_bias() const { return !accel_bias_m_s2.isZero(0.0); }
  [[nodiscard]] bool has_mag_correction() const {
    return !mag_hard_iron_uT.isZero(0.0) || !mag_soft_iron.isIdentity(0.0);
  }
};

/// Left and right camera, and the IMU.
struct RigCalibration {
  std::array<CameraCalibration, 2> cams;
  ImuCalibration imu;
  /// Where the IMU sits is known: the body frame is the IMU's by a camera-IMU calibration (a
  /// EuRoC folder's T_BS, a Kalibr cam0.T_cam_imu), or the file says the IMU's axes are cam0's
  /// (`imu_aligned_with_cam0: true`). False for a stereo-only calibration: the body is then
  /// cam0, and an IMU's gravity and rates would be taken in cam0's axes without anyone saying so.
  bool imu_extrinsic_known = false;

  /// T_left_right: right camera coordinates into the left camera.
  [[nodiscard]] SE3d T_cam0_cam1() const {
    return cams[0].T_body_cam.inverse() * cams[1].T_body_cam;
  }
  /// T_cam0_imu: IMU coordinates into the left camera (its rotation turns IMU gravity into the
  /// left camera's).
  [[nodiscard]] SE3d T_cam0_imu() const { return cams[0].T_body_cam.inverse() * imu.T_body_imu; }
};

}  // namespace wallar
