// SPDX-License-Identifier: Apache-2.0
/// @file imu_noise_calibration.cpp
/// @brief Allan deviation of each IMU axis of a still recording, and the noise terms.
#include "wallar/firmware/imu_noise_calibration.hpp"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/dsp/imu/static_init.hpp"

namespace wallar::firmware {
namespace {

std::optional<double> rms(const std::array<dsp::AllanNoise, 3>& axes,
                          std::optional<double> dsp::AllanNoise::*term) {
  double sum = 0.0;
  for (const dsp::AllanNoise& a : axes) {
    if (!(a.*term)) return std::nullopt;
    sum += *(a.*term) * *(a.*term);
  }
  return std::sqrt(sum / 3.0);
}

}  // namespace

ImuNoiseCalibration calibrate_imu_noise(const recording::EurocRecording& rec,
                                        double min_duration_s) {
  const std::string where = (rec.mav0 / "imu0").string();
  ImuNoiseCalibration out;
  if (rec.imu.size() < 2) throw_input_error(where, 0, "has no IMU samples");
  out.duration_s = ns_to_s(rec.imu.back().t_ns - rec.imu.front().t_ns);
  out.rate_hz = static_cast<double>(rec.imu.size() - 1) / out.duration_s;
  char msg[256];
  if (out.duration_s < min_duration_s) {
    std::snprintf(msg, sizeof msg,
                  "holds %.1f s of IMU samples: the noise needs at least %.0f s at rest (ten "
                  "minutes or more shows the random walk too)",
                  out.duration_s, min_duration_s);
    throw_input_error(where, 0, msg);
  }
  // At rest throughout: each ten-second window still (motion would read as noise).
  const TimeNs t0 = rec.imu.front().t_ns;
  const TimeNs t1 = rec.imu.back().t_ns;
  for (TimeNs t = t0; t + 10 * kNsPerS <= t1 + kNsPerS; t += 10 * kNsPerS) {
    const auto still = dsp::estimate_static_imu(rec.imu, t, std::min(t1, t + 10 * kNsPerS));
    if (still && !dsp::is_still(*still)) {
      std::snprintf(msg, sizeof msg,
                    "the IMU moves %.1f s into the recording (|accel| spread %.3f m/s^2): "
                    "record it at rest for the noise",
                    ns_to_s(t - t0), still->accel_std_m_s2);
      throw_input_error(where, 0, msg);
    }
  }
  std::vector<double> axis(rec.imu.size());
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < rec.imu.size(); ++i) axis[i] = rec.imu[i].gyro_rad_s[a];
    out.gyro[static_cast<std::size_t>(a)] =
        dsp::allan_noise(dsp::allan_deviation(axis, out.rate_hz));
    for (std::size_t i = 0; i < rec.imu.size(); ++i) axis[i] = rec.imu[i].accel_m_s2[a];
    out.accel[static_cast<std::size_t>(a)] =
        dsp::allan_noise(dsp::allan_deviation(axis, out.rate_hz));
  }
  out.gyro_noise_density = rms(out.gyro, &dsp::AllanNoise::white_density);
  out.gyro_random_walk = rms(out.gyro, &dsp::AllanNoise::random_walk);
  out.accel_noise_density = rms(out.accel, &dsp::AllanNoise::white_density);
  out.accel_random_walk = rms(out.accel, &dsp::AllanNoise::random_walk);
  return out;
}

}  // namespace wallar::firmware
