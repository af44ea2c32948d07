// SPDX-License-Identifier: Apache-2.0
/// @file imu_intrinsics.cpp
/// @brief Still poses, the accelerometer bias fit and the magnetometer ellipsoid fit.
#include "wallar/dsp/imu/imu_intrinsics.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>
#include <numbers>

namespace wallar::dsp {
namespace {

struct StillWindowStats {
  std::size_t samples = 0;
  Eigen::Vector3d accel_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_mean = Eigen::Vector3d::Zero();
  double accel_std = 0.0;  // RMS deviation from the mean (vector norm)
  double gyro_std = 0.0;
};

StillWindowStats still_window_stats(std::span<const ImuSample> w) {
  StillWindowStats s;
  s.samples = w.size();
  for (const ImuSample& x : w) {
    s.accel_mean += x.accel_m_s2;
    s.gyro_mean += x.gyro_rad_s;
  }
  const double n = static_cast<double>(w.size());
  s.accel_mean /= n;
  s.gyro_mean /= n;
  double va = 0.0, vg = 0.0;
  for (const ImuSample& x : w) {
    va += (x.accel_m_s2 - s.accel_mean).squaredNorm();
    vg += (x.gyro_rad_s - s.gyro_mean).squaredNorm();
  }
  s.accel_std = std::sqrt(va / n);
  s.gyro_std = std::sqrt(vg / n);
  return s;
}

double accel_angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / std::numbers::pi;
}

// The symmetric positive square root of a symmetric positive definite matrix.
Eigen::Matrix3d sqrtm_spd(const Eigen::Matrix3d& M) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(M);
  return es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() *
         es.eigenvectors().transpose();
}

}  // namespace

std::vector<StillPose> find_still_poses(std::span<const ImuSample> samples,
                                        const StillPoseParams& p) {
  std::vector<StillPose> poses;
  bool open = false;  // the last window was still and its pose may grow
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  auto close = [&] {
    if (!open) return;
    open = false;
    StillPose& pose = poses.back();
    pose.mean_accel_m_s2 = sum / static_cast<double>(pose.samples);
    if (pose.t_end_ns - pose.t_begin_ns < p.min_pose_ns) poses.pop_back();
  };
  std::size_t i = 0;
  while (i < samples.size()) {
    std::size_t j = i;
    while (j < samples.size() && samples[j].t_ns < samples[i].t_ns + p.window_ns) ++j;
    const std::span<const ImuSample> w = samples.subspan(i, j - i);
    const StillWindowStats s = still_window_stats(w);
    const bool still = s.samples >= 3 && s.gyro_mean.norm() <= p.max_gyro_mean_rad_s &&
                       s.gyro_std <= p.max_gyro_std_rad_s && s.accel_std <= p.max_accel_std_m_s2;
    if (!still) {
      close();
    } else {
      if (open && accel_angle_deg(sum / static_cast<double>(poses.back().samples), s.accel_mean) >
                      p.merge_angle_deg) {
        close();
      }
      if (!open) {
        poses.push_back(StillPose{w.front().t_ns, w.front().t_ns, 0, Eigen::Vector3d::Zero()});
        sum.setZero();
        open = true;
      }
      StillPose& pose = poses.back();
      pose.t_end_ns = w.back().t_ns;
      pose.samples += s.samples;
      sum += s.accel_mean * static_cast<double>(s.samples);
    }
    i = j;
  }
  close();
  return poses;
}

AccelBiasFit fit_accel_bias(std::span<const Eigen::Vector3d> a, double g) {
  AccelBiasFit fit;
  fit.poses = a.size();
  if (a.size() < 4 || !(g > 0.0)) return fit;
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& x : a) spread += x.normalized() * x.normalized().transpose();
  spread /= static_cast<double>(a.size());
  fit.direction_spread = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(spread).eigenvalues()(0);
  if (fit.direction_spread < kMinAccelDirectionSpread) return fit;
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (int it = 0; it < 30; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& x : a) {
      const Eigen::Vector3d d = x - b;
      const double n = d.norm();
      const Eigen::Vector3d J = -d / n;  // d(|x - b| - g)/db
      H += J * J.transpose();
      rhs -= J * (n - g);
    }
    const Eigen::Vector3d step = H.ldlt().solve(rhs);
    b += step;
    if (step.norm() < 1e-12) break;
  }
  double r2 = 0.0;
  for (const Eigen::Vector3d& x : a) r2 += std::pow((x - b).norm() - g, 2);
  fit.residual_rms_m_s2 = std::sqrt(r2 / static_cast<double>(a.size()));
  fit.bias_m_s2 = b;
  fit.solved = b.allFinite();
  return fit;
}

MagnetometerFit fit_magnetometer(std::span<const Eigen::Vector3d> m, double field_uT) {
  MagnetometerFit fit;
  fit.samples = m.size();
  if (m.size() < 50) return fit;
  // Centred and scaled to a unit RMS radius, so the 9 coefficients are of one size.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& x : m) mean += x;
  mean /= static_cast<double>(m.size());
  double r2 = 0.0;
  for (const Eigen::Vector3d& x : m) r2 += (x - mean).squaredNorm();
  const double scale = std::sqrt(r2 / static_cast<double>(m.size()));
  if (!(scale > 0.0)) return fit;
  // a x^2 + b y^2 + c z^2 + 2f yz + 2g xz + 2h xy + 2p x + 2q y + 2r z = 1
  Eigen::MatrixXd D(static_cast<Eigen::Index>(m.size()), 9);
  for (std::size_t i = 0; i < m.size(); ++i) {
    const Eigen::Vector3d u = (m[i] - mean) / scale;
    D.row(static_cast<Eigen::Index>(i)) << u.x() * u.x(), u.y() * u.y(), u.z() * u.z(),
        2.0 * u.y() * u.z(), 2.0 * u.x() * u.z(), 2.0 * u.x() * u.y(), 2.0 * u.x(), 2.0 * u.y(),
        2.0 * u.z();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(D, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd sv = svd.singularValues();
  if (!(sv(8) > 1e-6 * sv(0))) return fit;  // readings on a plane or a curve: no ellipsoid
  const Eigen::VectorXd v = svd.solve(Eigen::VectorXd::Ones(D.rows()));
  Eigen::Matrix3d A;
  A << v(0), v(5), v(4), v(5), v(1), v(3), v(4), v(3), v(2);
  const Eigen::Vector3d lin(v(6), v(7), v(8));
  const Eigen::Vector3d c = -A.ldlt().solve(lin);
  const double k = 1.0 + c.dot(A * c);
  if (!(k > 0.0)) return fit;
  const Eigen::Matrix3d M = A / k;  // (u - c)^T M (u - c) = 1
  if (!(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(M).eigenvalues()(0) > 0.0)) return fit;
  Eigen::Vector3d h = mean + scale * c;
  Eigen::Matrix3d S = sqrtm_spd(M) / scale;  // |S (m - h)| = 1
  double B = 1.0;
  if (field_uT > 0.0) {
    S *= field_uT;
    B = field_uT;
  } else {
    const double det = S.determinant();
    B = 1.0 / std::cbrt(det);
    S *= B;  // det S = 1: the sensor's own scale
  }
  // Levenberg-Marquardt on r_i = |S (m_i - h)| - B over h (3) and the symmetric S (6: 00 11 22
  // 01 02 12), B held: the algebraic fit's bias under noise goes, its gauge (the scale) stays.
  // A step is kept only when it lowers the cost: with readings over part of the sphere the
  // hard iron and the soft iron's scale along the unseen directions trade against each other,
  // and plain Gauss-Newton steps there diverge.
  using Vector9d = Eigen::Matrix<double, 9, 1>;
  using Matrix9d = Eigen::Matrix<double, 9, 9>;
  const auto cost = [&](const Eigen::Vector3d& hh, const Eigen::Matrix3d& SS) {
    double c2 = 0.0;
    for (const Eigen::Vector3d& x : m) c2 += std::pow((SS * (x - hh)).norm() - B, 2);
    return c2;
  };
  double current = cost(h, S);
  double lambda = 1e-3;
  for (int it = 0; it < 20; ++it) {
    Matrix9d H = Matrix9d::Zero();
    Vector9d g = Vector9d::Zero();
    for (const Eigen::Vector3d& x : m) {
      const Eigen::Vector3d d = x - h;
      const Eigen::Vector3d y = S * d;
      const double n = y.norm();
      if (!(n > 0.0)) continue;
      const Eigen::Vector3d e = y / n;
      Vector9d J;
      J.head<3>() = -(S.transpose() * e);
      J(3) = e(0) * d(0);
      J(4) = e(1) * d(1);
      J(5) = e(2) * d(2);
      J(6) = e(0) * d(1) + e(1) * d(0);
      J(7) = e(0) * d(2) + e(2) * d(0);
      J(8) = e(1) * d(2) + e(2) * d(1);
      H += J * J.transpose();
      g += J * (n - B);
    }
    bool improved = false;
    for (int tries = 0; tries < 8 && !improved; ++tries) {
      Matrix9d damped = H;
      damped.diagonal() += lambda * H.diagonal();
      const Vector9d step = -damped.ldlt().solve(g);
      if (!step.allFinite()) break;
      Eigen::Vector3d h2 = h + step.head<3>();
      Eigen::Matrix3d S2 = S;
      S2.diagonal() += step.segment<3>(3);
      S2(0, 1) += step(6);
      S2(1, 0) += step(6);
      S2(0, 2) += step(7);
      S2(2, 0) += step(7);
      S2(1, 2) += step(8);
      S2(2, 1) += step(8);
      const double next = cost(h2, S2);
      if (next < current) {
        improved = true;
        h = h2;
        S = S2;
        lambda = std::max(lambda * 0.1, 1e-9);
        const bool converged = current - next < 1e-12 * current;
        current = next;
        if (converged) it = 20;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  if (field_uT <= 0.0) {  // keep det S = 1 after the refinement moved the scale a little
    const double f = 1.0 / std::cbrt(S.determinant());
    S *= f;
    B *= f;
  }
  double res2 = 0.0;
  Eigen::Vector3d dir_mean = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> dirs;
  dirs.reserve(m.size());
  for (const Eigen::Vector3d& x : m) {
    const Eigen::Vector3d y = S * (x - h);
    res2 += std::pow(y.norm() - B, 2);
    dirs.push_back(y.normalized());
    dir_mean += dirs.back();
  }
  dir_mean /= static_cast<double>(m.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& u : dirs) cov += (u - dir_mean) * (u - dir_mean).transpose();
  cov /= static_cast<double>(m.size());
  fit.coverage = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvalues()(0);
  fit.residual_rms_uT = std::sqrt(res2 / static_cast<double>(m.size()));
  fit.hard_iron_uT = h;
  fit.soft_iron = S;
  fit.field_uT = B;
  fit.solved = h.allFinite() && S.allFinite() && fit.coverage >= kMinMagCoverage;
  return fit;
}

double field_heading_rad(const Eigen::Matrix3d& R_world_body, const Eigen::Vector3d& field_body) {
  const Eigen::Vector3d f = R_world_body * field_body;
  return std::atan2(f.y(), f.x());
}

}  // namespace wallar::dsp
