// SPDX-License-Identifier: Apache-2.0
/// @file attitude_errors.hpp
/// @brief Errors of an attitude + gyro-bias estimate against ground truth, and their summary.
///
/// Tilt (roll and pitch together) is the angle between the estimated and the true gravity
/// direction in the IMU frame: it ignores yaw, which an IMU without magnetometer cannot know,
/// and it has no Euler-angle singularity (EuRoC's IMU has its x axis up, where roll and pitch
/// Euler angles are degenerate).
///
/// Threading: pure functions; no state.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>

#include "wallar/core/time.hpp"

namespace wallar::dsp {

struct AttitudeErrorSample {
  TimeNs t_ns = 0;
  double tilt_rad = 0.0;  //!< angle between estimated and true gravity in the IMU frame
  Eigen::Vector3d gyro_bias_error_rad_s = Eigen::Vector3d::Zero();  //!< estimate - truth
};

/// Tilt error of q_world_imu_est against q_world_imu_true, and the bias error.
AttitudeErrorSample attitude_error(TimeNs t_ns, const Eigen::Quaterniond& q_world_imu_est,
                                   const Eigen::Vector3d& gyro_bias_est_rad_s,
                                   const Eigen::Quaterniond& q_world_imu_true,
                                   const Eigen::Vector3d& gyro_bias_true_rad_s);

struct AttitudeErrorSummary {
  std::size_t samples = 0;
  double duration_s = 0.0;
  double tilt_rms_deg = 0.0;
  double tilt_max_deg = 0.0;
  double tilt_final_deg = 0.0;
  double bias_error_final_rad_s = 0.0;  //!< norm of the bias error at the last sample
  double bias_error_max_rad_s = 0.0;    //!< largest norm over the whole run
  /// RMS of the bias error norm over the last `bias_window_s` of the run (the whole run when
  /// shorter): how well the bias is held once the filter has had time.
  double bias_error_rms_rad_s = 0.0;
  double bias_window_s = 0.0;  //!< the window actually used
};

/// Summarises errors given in increasing time.
AttitudeErrorSummary summarize_attitude_errors(std::span<const AttitudeErrorSample> errors,
                                               double bias_window_s = 100.0);

}  // namespace wallar::dsp
