// SPDX-License-Identifier: Apache-2.0
/// @file imu_attitude.cpp
/// @brief The attitude filter over a recording, compared with its ground truth.
#include "wallar/firmware/imu_attitude.hpp"

#include <cmath>

namespace wallar::firmware {

dsp::AttitudeFilterConfig attitude_config_for(const ImuCalibration& imu) {
  dsp::AttitudeFilterConfig config;
  if (imu.rate_hz > 0.0) {
    config.init_window_samples = static_cast<std::size_t>(std::max(20.0, std::round(imu.rate_hz)));
  }
  // The sensors' own noise figures where the calibration gives them (a datasheet's, or
  // measured by `wallar calibrate imu-noise`), not values tuned on one flight: the gyro's
  // density and bias walk, the accelerometer's white noise per sample. The filter's motion
  // term (vibration, the body's accelerations) is a model of the wearer, not of the sensor.
  if (imu.gyro_noise_density > 0.0) config.gyro_noise_rad_s_sqrt_hz = imu.gyro_noise_density;
  if (imu.gyro_random_walk > 0.0) config.gyro_bias_walk_rad_s2_sqrt_hz = imu.gyro_random_walk;
  if (imu.accel_noise_density > 0.0 && imu.rate_hz > 0.0) {
    config.accel_sensor_noise_m_s2 = imu.accel_noise_density * std::sqrt(imu.rate_hz);
  }
  // The accelerometer's bias and the magnetometer's iron, where `calibrate accel-mag` gave them.
  config.accel_bias_m_s2 = imu.accel_bias_m_s2;
  config.mag_hard_iron_uT = imu.mag_hard_iron_uT;
  config.mag_soft_iron = imu.mag_soft_iron;
  return config;
}

AttitudeRow attitude_row(const dsp::AttitudeFilter& filter, TimeNs t_ns, bool valid) {
  AttitudeRow r;
  r.t_ns = t_ns;
  r.valid = valid;
  if (valid) {
    r.q_world_imu = filter.q_world_imu();
    r.gravity_dir_imu = filter.gravity_dir_imu();
    r.gyro_bias_rad_s = filter.gyro_bias_rad_s();
  }
  return r;
}

AttitudeRun run_attitude_filter(const recording::EurocRecording& rec,
                                const dsp::AttitudeFilterConfig& config,
                                const std::function<void(const AttitudeRow&)>& row) {
  AttitudeRun run;
  run.samples = rec.imu.size();
  if (!rec.imu.empty()) run.duration_s = ns_to_s(rec.imu.back().t_ns - rec.imu.front().t_ns);
  dsp::AttitudeFilter filter(config);
  std::vector<dsp::AttitudeErrorSample> errors;
  errors.reserve(rec.imu.size());

  auto emit = [&](TimeNs t_ns, bool valid) {
    AttitudeRow r = attitude_row(filter, t_ns, valid);
    if (valid) {
      ++run.valid_rows;
      if (const auto gt = recording::ground_truth_at(rec.ground_truth, t_ns)) {
        r.error =
            dsp::attitude_error(t_ns, r.q_world_imu, r.gyro_bias_rad_s,
                                Eigen::Quaterniond(gt->T_world_body.linear()), gt->gyro_bias_rad_s);
        errors.push_back(*r.error);
      }
    }
    if (row) row(r);
  };

  std::size_t pending = 0;  // samples given to the filter before it was initialised
  for (std::size_t i = 0; i < rec.imu.size(); ++i) {
    const bool was_initialized = filter.initialized();
    const bool now_initialized = filter.update(rec.imu[i]);
    if (!was_initialized && !now_initialized) {
      ++pending;
      continue;
    }
    if (!was_initialized) {
      // Just initialised from a still window ending at this sample: the window's samples share
      // its estimate; earlier ones (not still) have none.
      const TimeNs window_begin_ns = filter.initial_estimate().t_begin_ns;
      for (std::size_t k = i - pending; k < i; ++k) {
        emit(rec.imu[k].t_ns, rec.imu[k].t_ns >= window_begin_ns);
      }
      pending = 0;
    }
    emit(rec.imu[i].t_ns, true);
  }
  for (std::size_t k = rec.imu.size() - pending; k < rec.imu.size(); ++k) {
    emit(rec.imu[k].t_ns, false);
  }
  run.counters = filter.counters();
  run.initial = filter.initial_estimate();
  if (!rec.ground_truth.empty()) run.errors = dsp::summarize_attitude_errors(errors);
  return run;
}

}  // namespace wallar::firmware
