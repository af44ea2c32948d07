// SPDX-License-Identifier: Apache-2.0
/// @file imu_cam_rotation.cpp
/// @brief IMU-to-camera rotation by Kabsch on matched rotation vectors.
#include "wallar/dsp/imu/imu_cam_rotation.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace wallar::dsp {

std::optional<Eigen::Vector3d> integrate_gyro_rotvec(std::span<const ImuSample> samples,
                                                     TimeNs t_begin_ns, TimeNs t_end_ns,
                                                     const Eigen::Vector3d& gyro_bias_rad_s) {
  if (samples.empty() || t_end_ns <= t_begin_ns || samples.front().t_ns > t_begin_ns ||
      samples.back().t_ns < t_end_ns) {
    return std::nullopt;
  }
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  // The rate between two samples is their linear interpolation: the rotation over [a, b] is
  // the mean of the rates at a and b times b - a. (Holding each sample's rate until the next
  // one would shift every integral by half a sample period, a time offset of its own.)
  const auto rate_at = [&](std::size_t i, TimeNs t) {
    const double span = static_cast<double>(samples[i + 1].t_ns - samples[i].t_ns);
    const double w = span > 0.0 ? static_cast<double>(t - samples[i].t_ns) / span : 0.0;
    return Eigen::Vector3d((1.0 - w) * samples[i].gyro_rad_s + w * samples[i + 1].gyro_rad_s);
  };
  for (std::size_t i = 0; i + 1 < samples.size(); ++i) {
    if (samples[i + 1].t_ns <= t_begin_ns) continue;
    if (samples[i].t_ns >= t_end_ns) break;
    const TimeNs a = std::max(samples[i].t_ns, t_begin_ns);
    const TimeNs b = std::min(samples[i + 1].t_ns, t_end_ns);
    if (b <= a) continue;
    const Eigen::Vector3d rotvec =
        (0.5 * (rate_at(i, a) + rate_at(i, b)) - gyro_bias_rad_s) * ns_to_s(b - a);
    const double angle = rotvec.norm();
    if (angle > 0.0) q = q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, rotvec / angle));
  }
  const Eigen::AngleAxisd aa(q.normalized());
  return aa.angle() * aa.axis();
}

std::optional<ImuCamRotationResult> solve_R_cam_imu(std::span<const Eigen::Vector3d> rotvec_imu,
                                                    std::span<const Eigen::Vector3d> rotvec_cam) {
  if (rotvec_imu.size() != rotvec_cam.size() || rotvec_imu.size() < 2) return std::nullopt;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();  // sum cam * imu^T
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < rotvec_imu.size(); ++i) {
    H += rotvec_cam[i] * rotvec_imu[i].transpose();
    scatter += rotvec_imu[i] * rotvec_imu[i].transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  ImuCamRotationResult r;
  r.R_cam_imu = svd.matrixU() * D * svd.matrixV().transpose();
  r.pairs = rotvec_imu.size();
  double sq = 0.0;
  for (std::size_t i = 0; i < rotvec_imu.size(); ++i) {
    sq += (rotvec_cam[i] - r.R_cam_imu * rotvec_imu[i]).squaredNorm();
  }
  r.residual_rms_rad = std::sqrt(sq / static_cast<double>(r.pairs));
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvalues();
  r.min_axis_spread = ev(2) > 0.0 ? std::sqrt(std::max(ev(1), 0.0) / ev(2)) : 0.0;
  return r;
}

}  // namespace wallar::dsp
