// SPDX-License-Identifier: Apache-2.0
/// @file imu_noise_calibration.hpp
/// @brief The IMU's noise densities and random walks from a recording of it at rest: the
/// Allan deviation of each gyro and accelerometer axis (dsp::allan_deviation) and its slopes
/// read as IEEE Std 952 does (dsp::allan_noise). What `wallar calibrate imu-noise` runs; the
/// result goes into an imu0/sensor.yaml (Kalibr's and EuRoC's names), which the rig carries.
///
/// Threading: plain function on the calling thread.
#pragma once

#include <array>
#include <optional>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/imu/allan_variance.hpp"

namespace wallar::firmware {

struct ImuNoiseCalibration {
  double duration_s = 0.0;
  double rate_hz = 0.0;                  //!< measured from the stamps
  std::array<dsp::AllanNoise, 3> gyro;   //!< per axis [rad/s]
  std::array<dsp::AllanNoise, 3> accel;  //!< per axis [m/s^2]
  /// The axes' root mean square (a filter takes one figure per sensor); none where an axis
  /// gave none.
  std::optional<double> gyro_noise_density, gyro_random_walk;
  std::optional<double> accel_noise_density, accel_random_walk;
};

/// Throws InputError naming the recording when it has too few IMU samples (under 60 s: the
/// white noise needs thousands of short clusters) or the IMU moved (not still over the whole
/// recording: motion would read as noise).
ImuNoiseCalibration calibrate_imu_noise(const recording::EurocRecording& rec,
                                        double min_duration_s = 60.0);

}  // namespace wallar::firmware
