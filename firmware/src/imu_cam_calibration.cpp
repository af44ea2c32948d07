// SPDX-License-Identifier: Apache-2.0
/// @file imu_cam_calibration.cpp
/// @brief IMU-to-camera rotation and time offset of a recording from gyro and images.
#include "wallar/firmware/imu_cam_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/dsp/imu/static_init.hpp"

namespace wallar::firmware {
namespace {

constexpr double kDeg = 180.0 / M_PI;

// A turning frame pair: its times and the camera's rotation between the two images.
struct TurningPair {
  TimeNs ta_ns;
  TimeNs tb_ns;
  Eigen::Vector3d rotvec_cam;
};

// The gyro's rotation over a camera window shifted into the IMU's clock (t_imu = t_cam + shift),
// integrating only the samples around it.
std::optional<Eigen::Vector3d> gyro_over(const std::vector<ImuSample>& imu, TimeNs ta, TimeNs tb,
                                         DurationNs shift_ns, const Eigen::Vector3d& bias) {
  const TimeNs a = ta + shift_ns;
  const TimeNs b = tb + shift_ns;
  const auto by_t = [](const ImuSample& s, TimeNs t) { return s.t_ns < t; };
  auto first = std::lower_bound(imu.begin(), imu.end(), a, by_t);
  auto last = std::lower_bound(first, imu.end(), b, by_t);
  if (first == imu.begin() || last == imu.end()) return std::nullopt;
  --first;  // the sample at or before a, and the one at or after b
  ++last;
  return dsp::integrate_gyro_rotvec(
      std::span<const ImuSample>(&*first, static_cast<std::size_t>(last - first)), a, b, bias);
}

// Robust cost of a time shift over the pairs: each pair's squared residual, capped at `cap`
// (a pair whose visual rotation is wrong weighs no more than the cap). With R, the rotation
// vectors are compared; without, their angles (which do not depend on R).
double shift_cost(const std::vector<ImuSample>& imu, const std::vector<TurningPair>& pairs,
                  DurationNs shift_ns, const Eigen::Vector3d& bias, const Eigen::Matrix3d* R,
                  double cap_rad) {
  double cost = 0.0;
  for (const TurningPair& p : pairs) {
    const auto g = gyro_over(imu, p.ta_ns, p.tb_ns, shift_ns, bias);
    double r2 = cap_rad * cap_rad;
    if (g) {
      r2 = R != nullptr ? (p.rotvec_cam - *R * *g).squaredNorm()
                        : std::pow(p.rotvec_cam.norm() - g->norm(), 2);
    }
    cost += std::min(r2, cap_rad * cap_rad);
  }
  return cost;
}

// The shift minimising shift_cost on a grid over [lo, hi], refined by the parabola through the
// best grid point and its neighbours.
DurationNs best_shift(const std::vector<ImuSample>& imu, const std::vector<TurningPair>& pairs,
                      DurationNs lo_ns, DurationNs hi_ns, DurationNs step_ns,
                      const Eigen::Vector3d& bias, const Eigen::Matrix3d* R, double cap_rad) {
  std::vector<double> cost;
  for (DurationNs s = lo_ns; s <= hi_ns; s += step_ns) {
    cost.push_back(shift_cost(imu, pairs, s, bias, R, cap_rad));
  }
  const auto best =
      static_cast<std::size_t>(std::min_element(cost.begin(), cost.end()) - cost.begin());
  double frac = 0.0;
  if (best > 0 && best + 1 < cost.size()) {
    const double denom = cost[best - 1] - 2.0 * cost[best] + cost[best + 1];
    if (denom > 0.0) frac = std::clamp(0.5 * (cost[best - 1] - cost[best + 1]) / denom, -0.5, 0.5);
  }
  return lo_ns + static_cast<DurationNs>(std::llround((static_cast<double>(best) + frac) *
                                                      static_cast<double>(step_ns)));
}

// The gyro bias from the first second, when the device was still then.
void still_bias(const recording::EurocRecording& rec, ImuCamCalibration& out) {
  const TimeNs t0_ns = rec.imu.front().t_ns;
  if (const auto still = dsp::estimate_static_imu(rec.imu, t0_ns, t0_ns + kNsPerS);
      still && dsp::is_still(*still)) {
    out.gyro_bias_rad_s = still->gyro_bias_rad_s;
    out.bias_from_still_window = true;
  }
}

DurationNs max_shift_of(const ImuCamCalibrationParams& params) {
  return static_cast<DurationNs>(std::llround(std::max(0.0, params.max_time_offset_ms) * 1e6));
}

// A frame pair the gyro says turned enough, and that it covers at every shift searched.
bool usable_pair(const recording::EurocRecording& rec, TimeNs ta, TimeNs tb,
                 const ImuCamCalibrationParams& params, ImuCamCalibration& out) {
  const DurationNs max_shift_ns = max_shift_of(params);
  const auto gyro = gyro_over(rec.imu, ta, tb, 0, out.gyro_bias_rad_s);
  if (!gyro || gyro->norm() * kDeg < params.min_rotation_deg) return false;
  return gyro_over(rec.imu, ta, tb, -max_shift_ns, out.gyro_bias_rad_s) &&
         gyro_over(rec.imu, ta, tb, max_shift_ns, out.gyro_bias_rad_s);
}

// The time offset and R from the turning pairs (the camera's rotation for each, however found).
void solve(const recording::EurocRecording& rec, const std::vector<TurningPair>& pairs,
           const ImuCamCalibrationParams& params, ImuCamCalibration& out) {
  const std::string where = rec.mav0.string();
  const DurationNs max_shift_ns = max_shift_of(params);
  char msg[256];
  // R at a shift: the pairs whose angles agree within the mismatch bound, solved.
  std::vector<Eigen::Vector3d> rv_imu, rv_cam;
  const auto solve_at = [&](DurationNs shift_ns) -> std::optional<dsp::ImuCamRotationResult> {
    rv_imu.clear();
    rv_cam.clear();
    out.angle_mismatches = 0;
    for (const TurningPair& p : pairs) {
      const auto g = gyro_over(rec.imu, p.ta_ns, p.tb_ns, shift_ns, out.gyro_bias_rad_s);
      if (!g || std::abs(p.rotvec_cam.norm() - g->norm()) * kDeg > params.max_angle_mismatch_deg) {
        ++out.angle_mismatches;
        continue;
      }
      rv_imu.push_back(*g);
      rv_cam.push_back(p.rotvec_cam);
    }
    if (rv_imu.size() < params.min_pairs) return std::nullopt;
    return dsp::solve_R_cam_imu(rv_imu, rv_cam);
  };

  DurationNs shift_ns = 0;
  if (max_shift_ns > 0 && pairs.size() >= params.min_pairs) {
    // The angles first (independent of R): 0.5 ms steps over the whole range; then R there,
    // and the rotation vectors around that shift in 0.1 ms steps (they see the offset in all
    // three axes, not only in the angle).
    const double cap = params.max_angle_mismatch_deg * 4.0 / kDeg;
    shift_ns = best_shift(rec.imu, pairs, -max_shift_ns, max_shift_ns, kNsPerMs / 2,
                          out.gyro_bias_rad_s, nullptr, cap);
    // Then, twice: R at the shift, the gyro bias left over (what the still window missed, or
    // all of it without one: a constant rate error turns every pair's rotation vector the same
    // way), and the shift again around the last one with the rotation vectors.
    for (int round = 0; round < 3; ++round) {
      const auto coarse = solve_at(shift_ns);
      if (!coarse) break;
      const Eigen::Matrix3d& R = coarse->R_cam_imu;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      double dt2 = 0.0;
      for (const TurningPair& p : pairs) {
        const auto g = gyro_over(rec.imu, p.ta_ns, p.tb_ns, shift_ns, out.gyro_bias_rad_s);
        if (!g) continue;
        const Eigen::Vector3d r = *g - R.transpose() * p.rotvec_cam;  // IMU frame
        if (r.norm() > cap) continue;
        const double dt = ns_to_s(p.tb_ns - p.ta_ns);
        sum += dt * r;
        dt2 += dt * dt;
      }
      if (dt2 > 0.0) out.gyro_bias_rad_s += sum / dt2;
      const DurationNs lo = std::max(-max_shift_ns, shift_ns - 3 * kNsPerMs);
      const DurationNs hi = std::min(max_shift_ns, shift_ns + 3 * kNsPerMs);
      shift_ns = best_shift(rec.imu, pairs, lo, hi, kNsPerMs / 10, out.gyro_bias_rad_s, &R, cap);
    }
    out.time_offset_estimated = true;
  }
  out.timeshift_cam_imu_ns = shift_ns;
  const auto solved = solve_at(shift_ns);
  if (rv_imu.size() < params.min_pairs) {
    std::snprintf(msg, sizeof msg,
                  "only %zu frame pairs turn more than %.1f deg and match the gyro (need %zu; %zu "
                  "turning, %zu without a visual rotation): the camera must turn about two axes",
                  rv_imu.size(), params.min_rotation_deg, params.min_pairs, out.turning_pairs,
                  out.visual_failures);
    throw_input_error(where, 0, msg);
  }
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
}

}  // namespace

ImuCamCalibration calibrate_imu_cam(const recording::EurocRecording& rec,
                                    const ImuCamCalibrationParams& params) {
  ImuCamCalibration out;
  if (rec.imu.empty()) throw_input_error(rec.mav0.string(), 0, "has no IMU samples");
  still_bias(rec, out);
  const auto& cam = rec.cams[0];
  std::vector<TurningPair> pairs;
  const std::size_t step = static_cast<std::size_t>(std::max(1, params.frame_step));
  for (std::size_t k = 0; k + step < cam.frames.size(); k += step) {
    ++out.frame_pairs;
    const TimeNs ta = cam.frames[k].t_ns;
    const TimeNs tb = cam.frames[k + step].t_ns;
    if (!usable_pair(rec, ta, tb, params, out)) continue;
    ++out.turning_pairs;
    const Image a = recording::load_frame_gray(rec, 0, cam.frames[k]);
    const Image b = recording::load_frame_gray(rec, 0, cam.frames[k + step]);
    const auto visual = dsp::camera_rotation_between(a, b, cam.calib, params.visual);
    if (!visual) {
      ++out.visual_failures;
      continue;
    }
    pairs.push_back({ta, tb, visual->rotvec_cam0_cam1});
  }
  solve(rec, pairs, params, out);
  return out;
}

ImuCamCalibration calibrate_imu_cam(const recording::EurocRecording& rec,
                                    std::span<const PoseRecord> trajectory,
                                    const ImuCamCalibrationParams& params) {
  ImuCamCalibration out;
  out.from_track = true;
  if (rec.imu.empty()) throw_input_error(rec.mav0.string(), 0, "has no IMU samples");
  still_bias(rec, out);
  // cam0 in the tracker's world: the body's pose times cam0's place on it.
  const SE3d T_body_cam0 = rec.rig().cams[0].T_body_cam;
  std::vector<const PoseRecord*> tracked;
  for (const PoseRecord& r : trajectory) {
    if (r.state == dsp::TrackingState::kTracking && r.rejected == nullptr) tracked.push_back(&r);
  }
  std::vector<TurningPair> pairs;
  const std::size_t step = static_cast<std::size_t>(std::max(1, params.frame_step));
  for (std::size_t k = 0; k + step < tracked.size(); k += step) {
    ++out.frame_pairs;
    const TimeNs ta = tracked[k]->t_ns;
    const TimeNs tb = tracked[k + step]->t_ns;
    if (!usable_pair(rec, ta, tb, params, out)) continue;
    ++out.turning_pairs;
    const Eigen::Matrix3d R_a = (tracked[k]->T_world_body * T_body_cam0).linear();
    const Eigen::Matrix3d R_b = (tracked[k + step]->T_world_body * T_body_cam0).linear();
    const Eigen::AngleAxisd aa(R_a.transpose() * R_b);
    pairs.push_back({ta, tb, aa.angle() * aa.axis()});
  }
  out.visual_failures = trajectory.size() - tracked.size();
  solve(rec, pairs, params, out);
  return out;
}

}  // namespace wallar::firmware
