// SPDX-License-Identifier: Apache-2.0
/// @file accel_mag_calibration.cpp
/// @brief Still poses and the bias fit, the ellipsoid fit, and the checks against ground truth.
#include "wallar/firmware/accel_mag_calibration.hpp"

#include <cmath>
#include <numbers>

#include "wallar/core/error.hpp"

namespace wallar::firmware {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// Circular standard deviation of angles: sqrt(-2 ln R), R the mean resultant length [rad].
double circular_std_rad(const std::vector<double>& angles_rad) {
  double c = 0.0, s = 0.0;
  for (const double a : angles_rad) {
    c += std::cos(a);
    s += std::sin(a);
  }
  const double n = static_cast<double>(angles_rad.size());
  const double R = std::min(1.0, std::hypot(c, s) / n);
  return R > 0.0 ? std::sqrt(-2.0 * std::log(R)) : std::numbers::pi;
}

}  // namespace

AccelMagCalibration calibrate_accel_mag(const recording::EurocRecording& rec,
                                        const AccelMagCalibrationParams& params) {
  if (rec.imu.size() < 2) throw_input_error((rec.mav0 / "imu0").string(), 0, "has no IMU samples");
  AccelMagCalibration out;
  out.samples = rec.imu.size();
  out.duration_s = ns_to_s(rec.imu.back().t_ns - rec.imu.front().t_ns);
  out.poses = dsp::find_still_poses(rec.imu, params.still);
  std::vector<Eigen::Vector3d> means;
  means.reserve(out.poses.size());
  for (const dsp::StillPose& p : out.poses) means.push_back(p.mean_accel_m_s2);
  out.accel = dsp::fit_accel_bias(means, params.gravity_m_s2);

  std::vector<Eigen::Vector3d> readings;
  for (const ImuSample& s : rec.imu) {
    if (s.mag_uT && s.mag_uT->allFinite()) readings.push_back(*s.mag_uT);
  }
  out.mag_samples = readings.size();
  if (!readings.empty()) out.mag = dsp::fit_magnetometer(readings, params.field_uT);

  if (rec.ground_truth.empty()) return out;
  // The ground truth is on the cameras' clock; an IMU stamp is that plus the time shift.
  const DurationNs shift_ns = rec.imu_calib.timeshift_cam_imu_ns;
  const auto truth_at = [&](TimeNs t_imu_ns) {
    return recording::ground_truth_at(rec.ground_truth, t_imu_ns - shift_ns);
  };
  Eigen::Vector3d bias_sum = Eigen::Vector3d::Zero();
  double raw2 = 0.0, fit2 = 0.0;
  std::size_t n = 0;
  for (const dsp::StillPose& p : out.poses) {
    const auto gt = truth_at((p.t_begin_ns + p.t_end_ns) / 2);
    if (!gt) continue;
    bias_sum += gt->accel_bias_m_s2;
    const Eigen::Vector3d up = gt->up_body();
    const auto angle = [&](const Eigen::Vector3d& a) {
      return std::atan2(a.cross(up).norm(), a.dot(up)) * kRadToDeg;
    };
    raw2 += std::pow(angle(p.mean_accel_m_s2), 2);
    fit2 += std::pow(angle(p.mean_accel_m_s2 - out.accel.bias_m_s2), 2);
    ++n;
  }
  if (n > 0) {
    out.accel_bias_truth_m_s2 = bias_sum / static_cast<double>(n);
    out.tilt_error_raw_deg = std::sqrt(raw2 / static_cast<double>(n));
    if (out.accel.solved) out.tilt_error_deg = std::sqrt(fit2 / static_cast<double>(n));
  }
  if (out.mag) {
    std::vector<double> raw, fixed;
    for (const ImuSample& s : rec.imu) {
      if (!s.mag_uT) continue;
      const auto gt = truth_at(s.t_ns);
      if (!gt) continue;
      const Eigen::Matrix3d R = gt->T_world_body.linear();
      raw.push_back(dsp::field_heading_rad(R, *s.mag_uT));
      fixed.push_back(
          dsp::field_heading_rad(R, out.mag->soft_iron * (*s.mag_uT - out.mag->hard_iron_uT)));
    }
    if (!raw.empty()) {
      out.heading_spread_raw_deg = circular_std_rad(raw) * kRadToDeg;
      if (out.mag->solved) out.heading_spread_deg = circular_std_rad(fixed) * kRadToDeg;
    }
  }
  return out;
}

}  // namespace wallar::firmware
