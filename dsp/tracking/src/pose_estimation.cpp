// SPDX-License-Identifier: Apache-2.0
/// @file pose_estimation.cpp
/// @brief RANSAC over 3-point rigid alignments, then Huber Gauss-Newton on reprojection errors.
#include "wallar/dsp/tracking/pose_estimation.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <limits>

namespace wallar::dsp {
namespace {

bool has_right(const PoseObservation& o) { return std::isfinite(o.u_right_px); }

/// splitmix64: a tiny deterministic generator (no std distributions: they differ by library).
std::uint64_t next_random(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

int count_inliers(const StereoIntrinsics& K, std::span<const PoseObservation> obs,
                  const SE3d& T, double inlier_sq) {
  int n = 0;
  for (const PoseObservation& o : obs) n += reprojection_error_sq(K, T, o) < inlier_sq ? 1 : 0;
  return n;
}

}  // namespace

double reprojection_error_sq(const StereoIntrinsics& K, const SE3d& T_cam_world,
                             const PoseObservation& obs) {
  const Eigen::Vector3d p = T_cam_world * obs.p_world;
  if (p.z() < 1e-3) return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d uvr = K.project(p);
  const double du = uvr.x() - obs.u_px, dv = uvr.y() - obs.v_px;
  double e = du * du + dv * dv;
  if (has_right(obs)) {
    const double dr = uvr.z() - obs.u_right_px;
    e = 0.5 * (e + dr * dr + dv * dv);  // the mean of the two eyes' squared errors
  }
  return e;
}

SE3d refine_pose(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
                 std::span<const std::uint8_t> use, SE3d T, const PoseParams& params) {
  for (int it = 0; it < params.gn_iterations; ++it) {
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
      const Eigen::Matrix<double, 3, 6> J = Jp * Jxi;
      const int rows = has_right(o) ? 3 : 2;
      const Eigen::Vector3d r(uvr.x() - o.u_px, uvr.y() - o.v_px,
                              has_right(o) ? uvr.z() - o.u_right_px : 0.0);
      for (int k = 0; k < rows; ++k) {
        const double a = std::abs(r[k]);
        const double w = a <= params.huber_px ? 1.0 : params.huber_px / a;
        H.noalias() += w * J.row(k).transpose() * J.row(k);
        g.noalias() += w * J.row(k).transpose() * r[k];
      }
      ++used;
    }
    if (used < 3) break;
    const Eigen::Matrix<double, 6, 1> dx = H.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    T = orthonormalised(se3_exp(dx) * T);
    if (dx.squaredNorm() < 1e-12) break;
  }
  return T;
}

PoseResult estimate_pose(const StereoIntrinsics& K, std::span<const PoseObservation> observations,
                         const SE3d& prior, std::span<std::uint8_t> inlier, std::uint64_t seed,
                         const PoseParams& params) {
  PoseResult result;
  const double inlier_sq = params.inlier_px * params.inlier_px;
  const int n = static_cast<int>(observations.size());
  SE3d best = prior;
  int best_inliers = count_inliers(K, observations, prior, inlier_sq);
  // Stereo observations give a 3-D point in the current camera; three of them fix the pose.
  int stereo = 0;
  for (const PoseObservation& o : observations) stereo += has_right(o) ? 1 : 0;
  if (stereo >= 3 && best_inliers < (n * 9) / 10) {
    std::uint64_t state = seed;
    for (int it = 0; it < params.ransac_iterations; ++it) {
      Eigen::Matrix3d src, dst;  // columns: world points, camera points
      std::array<int, 3> pick{-1, -1, -1};
      int got = 0;
      for (int tries = 0; got < 3 && tries < 64; ++tries) {
        const int i = static_cast<int>(next_random(state) % static_cast<std::uint64_t>(n));
        const PoseObservation& o = observations[static_cast<std::size_t>(i)];
        if (!has_right(o) || i == pick[0] || i == pick[1]) continue;
        const double d = o.u_px - o.u_right_px;
        if (!(d > 0.5)) continue;
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
      SE3d T;
      T.matrix() = M;
      if (!T.matrix().allFinite()) continue;
      const int inl = count_inliers(K, observations, T, inlier_sq);
      if (inl > best_inliers) {
        best_inliers = inl;
        best = T;
        result.from_ransac = true;
        if (inl > (n * 9) / 10) break;
      }
    }
  }
  // Refine on the inliers, re-classify with the refined pose, refine again.
  SE3d T = best;
  for (int pass = 0; pass < 2; ++pass) {
    for (int i = 0; i < n; ++i) {
      inlier[static_cast<std::size_t>(i)] =
          reprojection_error_sq(K, T, observations[static_cast<std::size_t>(i)]) <
                  inlier_sq * (pass == 0 ? 4.0 : 1.0)
              ? 1
              : 0;
    }
    T = refine_pose(K, observations, inlier, T, params);
  }
  int count = 0;
  double sum_sq = 0.0;
  for (int i = 0; i < n; ++i) {
    const double e = reprojection_error_sq(K, T, observations[static_cast<std::size_t>(i)]);
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
