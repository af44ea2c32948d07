// SPDX-License-Identifier: Apache-2.0
/// @file imu_attitude.hpp
/// @brief The attitude filter run over a whole recording, with errors against its ground truth:
/// what `wallar imu` writes and what the accuracy test asserts, from one code path.
///
/// Threading: plain functions; the callback runs on the calling thread.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/imu/attitude_errors.hpp"
#include "wallar/dsp/imu/attitude_filter.hpp"

namespace wallar::firmware {

/// One output row: the state after the filter took the sample at t_ns.
struct AttitudeRow {
  TimeNs t_ns = 0;
  Eigen::Quaterniond q_world_imu = Eigen::Quaterniond::Identity();
  Eigen::Vector3d gravity_dir_imu = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();
  bool valid = false;  //!< false for samples before the filter's first still window
  std::optional<dsp::AttitudeErrorSample> error;  //!< when ground truth covers t_ns
};

struct AttitudeRun {
  std::size_t samples = 0;
  std::size_t valid_rows = 0;                       //!< rows with an estimate
  double duration_s = 0.0;                          //!< first to last IMU sample
  std::optional<dsp::AttitudeErrorSummary> errors;  //!< when the recording has ground truth
  dsp::AttitudeFilterCounters counters;
  dsp::StaticImuEstimate initial;  //!< the still window the filter started from
};

/// The row for a sample at t_ns: the filter's current state when valid (the filter is
/// initialised), an invalid row otherwise. Recordings and the live command build rows here.
AttitudeRow attitude_row(const dsp::AttitudeFilter& filter, TimeNs t_ns, bool valid);

/// The filter's configuration for an IMU: the still window is one second at its rate (at least
/// 20 samples; the filter's default of 200 when the rate is unknown); the gyro's noise density
/// and bias random walk from the calibration when it gives them (the filter's defaults when
/// zero).
dsp::AttitudeFilterConfig attitude_config_for(const ImuCalibration& imu);
/// The same for a recording's IMU (its sensor.yaml).
inline dsp::AttitudeFilterConfig attitude_config_for(const recording::EurocRecording& rec) {
  return attitude_config_for(rec.imu_calib);
}

/// Runs the filter over rec.imu and calls `row` once per IMU sample, in order. Samples of the
/// still window the filter starts from get the window's estimate (the device did not move);
/// samples before it, in windows that were not still, are invalid rows.
AttitudeRun run_attitude_filter(const recording::EurocRecording& rec,
                                const dsp::AttitudeFilterConfig& config,
                                const std::function<void(const AttitudeRow&)>& row = {});

}  // namespace wallar::firmware
