// SPDX-License-Identifier: Apache-2.0
/// @file imu_cam_calibration.cpp
/// @brief IMU-to-camera rotation of a recording from gyro and images.
#include "wallar/firmware/imu_cam_calibration.hpp"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/dsp/imu/static_init.hpp"

namespace wallar::firmware {

ImuCamCalibration calibrate_imu_cam(const recording::EurocRecording& rec,
                                    const ImuCamCalibrationParams& params) {
  constexpr double kDeg = 180.0 / M_PI;
  ImuCamCalibration out;
  const std::string where = rec.mav0.string();
  if (rec.imu.empty()) throw_input_error(where, 0, "has no IMU samples");
  const auto& cam = rec.cams[0];
  // Gyro bias from the first second, when the device was still then.
  const TimeNs t0_ns = rec.imu.front().t_ns;
  if (const auto still = dsp::estimate_static_imu(rec.imu, t0_ns, t0_ns + kNsPerS);
      still && dsp::is_still(*still)) {
    out.gyro_bias_rad_s = still->gyro_bias_rad_s;
    out.bias_from_still_window = true;
  }
  std::vector<Eigen::Vector3d> rv_imu, rv_cam;
  const std::size_t step = static_cast<std::size_t>(std::max(1, params.frame_step));
  for (std::size_t k = 0; k + step < cam.frames.size(); k += step) {
    ++out.frame_pairs;
    const TimeNs ta = cam.frames[k].t_ns;
    const TimeNs tb = cam.frames[k + step].t_ns;
    const auto gyro = dsp::integrate_gyro_rotvec(rec.imu, ta, tb, out.gyro_bias_rad_s);
    if (!gyro || gyro->norm() * kDeg < params.min_rotation_deg) continue;
    ++out.turning_pairs;
    const Image a = recording::load_png_gray(cam.image_path(cam.frames[k]), cam.calib.width_px,
                                             cam.calib.height_px);
    const Image b = recording::load_png_gray(cam.image_path(cam.frames[k + step]),
                                             cam.calib.width_px, cam.calib.height_px);
    const auto visual = dsp::camera_rotation_between(a, b, cam.calib, params.visual);
    if (!visual) {
      ++out.visual_failures;
      continue;
    }
    if (std::abs(visual->rotvec_cam0_cam1.norm() - gyro->norm()) * kDeg >
        params.max_angle_mismatch_deg) {
      ++out.angle_mismatches;
      continue;
    }
    rv_imu.push_back(*gyro);
    rv_cam.push_back(visual->rotvec_cam0_cam1);
  }
  char msg[256];
  if (rv_imu.size() < params.min_pairs) {
    std::snprintf(msg, sizeof msg,
                  "only %zu frame pairs turn more than %.1f deg and match the gyro (need %zu; %zu "
                  "turning, %zu without a visual rotation): the camera must turn about two axes",
                  rv_imu.size(), params.min_rotation_deg, params.min_pairs, out.turning_pairs,
                  out.visual_failures);
    throw_input_error(where, 0, msg);
  }
  const auto solved = dsp::solve_R_cam_imu(rv_imu, rv_cam);
  if (!solved || solved->min_axis_spread < params.min_axis_spread) {
    std::snprintf(msg, sizeof msg,
                  "the %zu turning pairs turn about one axis only (spread %.3f < %.3f): turn the "
                  "camera about a second axis",
                  rv_imu.size(), solved ? solved->min_axis_spread : 0.0, params.min_axis_spread);
    throw_input_error(where, 0, msg);
  }
  out.solved = *solved;
  const Eigen::Matrix3d R_file = rec.rig().T_cam0_imu().linear();
  out.vs_calibration_deg =
      Eigen::AngleAxisd(out.solved.R_cam_imu * R_file.transpose()).angle() * kDeg;
  return out;
}

}  // namespace wallar::firmware
