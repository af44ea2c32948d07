// SPDX-License-Identifier: Apache-2.0
/// @file pose_estimation.cpp
/// @brief RANSAC over 3-point rigid alignments, then Huber Gauss-Newton on reprojection errors.
#include "wallar/dsp/tracking/pose_estimation.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>

#include "wallar/core/hash.hpp"

namespace wallar::dsp {
namespace {

bool has_right(const PoseObservation& o) { return std::isfinite(o.u_right_px); }

/// splitmix64: a tiny deterministic generator (no std distributions: they differ by library).
std::uint64_t next_random(std::uint64_t& state) { return core::splitmix64_next(state); }

int count_inliers(const StereoIntrinsics& K, std::span<const PoseObservation> obs, const SE3d& T,
                  double inlier_sq, double disparity_sigma_px) {
  int n = 0;
  for (const PoseObservation& o : obs) {
    n += reprojection_error_sq(K, T, o, disparity_sigma_px) < inlier_sq ? 1 : 0;
  }
  return n;
}

}  // namespace

double disparity_weight(const StereoIntrinsics& K, const PoseObservation& obs, double depth_m,
                        double sigma_px) {
  if (!(obs.sigma_m > 0.0f) || !(depth_m > 0.0)) return 1.0;
  // d = f b / z, so a depth uncertain by sigma_z moves the disparity by f b sigma_z / z^2.
  const double sigma_d =
      K.f_px * K.baseline_m * static_cast<double>(obs.sigma_m) / (depth_m * depth_m);
  const double q = sigma_d / sigma_px;
  return 1.0 / (1.0 + q * q);
}

double reprojection_error_sq(const StereoIntrinsics& K, const SE3d& T_cam_world,
                             const PoseObservation& obs, double disparity_sigma_px) {
  const Eigen::Vector3d p = T_cam_world * obs.p_world;
  if (p.z() < 1e-3) return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d uvr = K.project(p);
  const double du = uvr.x() - obs.u_px, dv = uvr.y() - obs.v_px;
  double e = du * du + dv * dv;
  if (has_right(obs)) {
    // The disparity residual, weighted by what the map point's depth uncertainty allows.
    const double dd = (uvr.x() - uvr.z()) - (obs.u_px - obs.u_right_px);
    e += disparity_weight(K, obs, p.z(), disparity_sigma_px) * dd * dd;
  }
  return e;
}

namespace {

enum class Kernel : std::uint8_t { kHuber, kCauchy };

/// Gauss-Newton on the observations flagged in `use` with a robust kernel of scale `scale_px`.
SE3d refine_with(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
                 std::span<const std::uint8_t> use, SE3d T, double scale_px, Kernel kernel,
                 int iterations, const PoseParams& params) {
  const double disparity_sigma_px = params.disparity_sigma_px;
  for (int it = 0; it < iterations; ++it) {
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    int used = 0;
    for (std::size_t i = 0; i < observations.size(); ++i) {
      if (use[i] == 0) continue;
      const PoseObservation& o = observations[i];
      const Eigen::Vector3d p = T * o.p_world;
      if (p.z() < 1e-3) continue;
      const Eigen::Vector3d uvr = K.project(p);
      const Eigen::Matrix3d Jp = K.project_jacobian(p);
      // Left perturbation T <- exp(xi) T: d p / d xi = [I, -[p]x].
      Eigen::Matrix<double, 3, 6> Jxi;
      Jxi.leftCols<3>().setIdentity();
      Jxi.rightCols<3>() = -skew(p);
      Eigen::Matrix<double, 3, 6> J = Jp * Jxi;
      // Rows: left u, left v, and the disparity u - u_right (weighted by the point's depth
      // uncertainty, so far points steer the rotation more than the translation).
      const int rows = has_right(o) ? 3 : 2;
      Eigen::Vector3d r(uvr.x() - o.u_px, uvr.y() - o.v_px, 0.0);
      const double w_obs = o.weight;
      double row_weight[3] = {w_obs, w_obs, w_obs};
      if (has_right(o)) {
        J.row(2) = J.row(0) - J.row(2);
        r[2] = (uvr.x() - uvr.z()) - (o.u_px - o.u_right_px);
        row_weight[2] = w_obs * disparity_weight(K, o, p.z(), disparity_sigma_px);
      }
      for (int k = 0; k < rows; ++k) {
        const double a = std::abs(r[k]) * std::sqrt(row_weight[k]);
        double w = 1.0;
        if (kernel == Kernel::kHuber) {
          w = a <= scale_px ? 1.0 : scale_px / a;
        } else {
          const double q = a / scale_px;
          w = 1.0 / (1.0 + q * q);
        }
        w *= row_weight[k];
        H.noalias() += w * J.row(k).transpose() * J.row(k);
        g.noalias() += w * J.row(k).transpose() * r[k];
      }
      ++used;
    }
    if (used < 3) break;
    if (params.rotation_prior_weight > 0.0) {
      // Left perturbation: R <- exp(phi) R, so log(exp(phi) R R_p^T) ~ phi + log(R R_p^T).
      const Eigen::AngleAxisd e(T.linear() * params.R_prior_cw.transpose());
      H.bottomRightCorner<3, 3>().diagonal().array() += params.rotation_prior_weight;
      g.tail<3>() += params.rotation_prior_weight * e.angle() * e.axis();
    }
    const Eigen::Matrix<double, 6, 1> dx = H.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    T = orthonormalised(se3_exp(dx) * T);
    if (dx.squaredNorm() < 1e-12) break;
  }
  return T;
}

/// From a starting pose: a wide Cauchy pass over every observation (a prediction several pixels
/// off still pulls the pose into place, gross outliers barely count), then inliers classified at
/// twice and once the inlier radius with Huber refinements between. Returns the inlier count.
int polish(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
           std::span<std::uint8_t> inlier, SE3d& T, const PoseParams& params) {
  const double inlier_sq = params.inlier_px * params.inlier_px;
  const int n = static_cast<int>(observations.size());
  std::fill(inlier.begin(), inlier.end(), std::uint8_t{1});
  T = refine_with(K, observations, inlier, T, params.wide_px, Kernel::kCauchy, params.gn_iterations,
                  params);
  for (int pass = 0; pass < 2; ++pass) {
    for (int i = 0; i < n; ++i) {
      inlier[static_cast<std::size_t>(i)] =
          reprojection_error_sq(K, T, observations[static_cast<std::size_t>(i)],
                                params.disparity_sigma_px) < inlier_sq * (pass == 0 ? 4.0 : 1.0)
              ? 1
              : 0;
    }
    T = refine_with(K, observations, inlier, T, params.huber_px, Kernel::kHuber,
                    params.gn_iterations, params);
  }
  return count_inliers(K, observations, T, inlier_sq, params.disparity_sigma_px);
}

}  // namespace

SE3d refine_pose(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
                 std::span<const std::uint8_t> use, SE3d T, const PoseParams& params) {
  return refine_with(K, observations, use, T, params.huber_px, Kernel::kHuber, params.gn_iterations,
                     params);
}

PoseResult estimate_pose(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
                         const SE3d& prior, std::span<std::uint8_t> inlier, std::uint64_t seed,
                         const PoseParams& params) {
  PoseResult result;
  const double inlier_sq = params.inlier_px * params.inlier_px;
  // Hypotheses are scored with a wider radius: three noisy stereo points fix the pose only
  // roughly (far points' depths are uncertain), and the polish below does the rest.
  const double score_sq =
      inlier_sq * params.hypothesis_radius_factor * params.hypothesis_radius_factor;
  const int n = static_cast<int>(observations.size());
  // The prior first: polished, it is the answer whenever the prediction was near.
  SE3d T = prior;
  int inliers = polish(K, observations, inlier, T, params);
  // Stereo observations give a 3-D point in the current camera; three of them fix the pose.
  int stereo = 0;
  for (const PoseObservation& o : observations) stereo += has_right(o) ? 1 : 0;
  if (stereo >= 3 && inliers < (n * 8) / 10) {
    std::uint64_t state = seed;
    SE3d best = prior;
    int best_score = count_inliers(K, observations, prior, score_sq, params.disparity_sigma_px);
    bool found = false;
    for (int it = 0; it < params.ransac_iterations; ++it) {
      Eigen::Matrix3d src, dst;  // columns: world points, camera points
      std::array<int, 3> pick{-1, -1, -1};
      int got = 0;
      for (int tries = 0; got < 3 && tries < 64; ++tries) {
        const int i = static_cast<int>(next_random(state) % static_cast<std::uint64_t>(n));
        const PoseObservation& o = observations[static_cast<std::size_t>(i)];
        if (!has_right(o) || i == pick[0] || i == pick[1]) continue;
        const double d = o.u_px - o.u_right_px;
        if (!(d > params.min_sample_disparity_px)) continue;
        pick[static_cast<std::size_t>(got)] = i;
        src.col(got) = o.p_world;
        dst.col(got) = K.triangulate(o.u_px, o.v_px, d);
        ++got;
      }
      if (got < 3) break;
      // Degenerate samples (nearly collinear) give no rotation.
      const double area = (dst.col(1) - dst.col(0)).cross(dst.col(2) - dst.col(0)).norm();
      if (area < 1e-4) continue;
      const Eigen::Matrix4d M = Eigen::umeyama(src, dst, false);
      SE3d H;
      H.matrix() = M;
      if (!H.matrix().allFinite()) continue;
      const int score = count_inliers(K, observations, H, score_sq, params.disparity_sigma_px);
      if (score > best_score) {
        best_score = score;
        best = H;
        found = true;
        if (score > (n * 9) / 10) break;
      }
    }
    if (found) {
      SE3d T2 = best;
      const int inliers2 = polish(K, observations, inlier, T2, params);
      if (inliers2 > inliers) {
        T = T2;
        inliers = inliers2;
        result.from_ransac = true;
      }
    }
  }
  int count = 0;
  double sum_sq = 0.0;
  for (int i = 0; i < n; ++i) {
    const double e = reprojection_error_sq(K, T, observations[static_cast<std::size_t>(i)],
                                           params.disparity_sigma_px);
    const bool in = e < inlier_sq;
    inlier[static_cast<std::size_t>(i)] = in ? 1 : 0;
    if (in) {
      ++count;
      sum_sq += e;
    }
  }
  result.T_cam_world = T;
  result.inliers = count;
  result.rms_px = count > 0 ? std::sqrt(sum_sq / count) : 0.0;
  result.ok = count >= params.min_inliers && T.matrix().allFinite();
  return result;
}

}  // namespace wallar::dsp
