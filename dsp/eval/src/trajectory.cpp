// SPDX-License-Identifier: Apache-2.0
/// @file trajectory.cpp
/// @brief ATE and RPE of an estimated trajectory against ground truth.
#include "wallar/dsp/eval/trajectory.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace wallar::dsp {
namespace {

bool sorted(std::span<const StampedPose> poses) {
  return std::is_sorted(poses.begin(), poses.end(),
                        [](const StampedPose& a, const StampedPose& b) { return a.t_ns < b.t_ns; });
}

// gt at t_ns, interpolated between the bracketing samples, when both are within max_dt_ns.
std::optional<SE3d> interpolate(std::span<const StampedPose> gt, TimeNs t_ns, TimeNs max_dt_ns) {
  const auto after = std::lower_bound(gt.begin(), gt.end(), t_ns,
                                      [](const StampedPose& p, TimeNs t) { return p.t_ns < t; });
  if (after != gt.end() && after->t_ns == t_ns) return after->T_world_body;
  if (after == gt.begin() || after == gt.end()) return std::nullopt;
  const StampedPose& b = *after;
  const StampedPose& a = *(after - 1);
  if (t_ns - a.t_ns > max_dt_ns || b.t_ns - t_ns > max_dt_ns) return std::nullopt;
  const double f = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  const Eigen::Quaterniond qa(a.T_world_body.linear()), qb(b.T_world_body.linear());
  SE3d T = SE3d::Identity();
  T.linear() = qa.slerp(f, qb).normalized().toRotationMatrix();
  T.translation() = (1.0 - f) * a.T_world_body.translation() + f * b.T_world_body.translation();
  return T;
}

// An RPE pair's span differs from rpe_delta_s by less than this fraction of it.
constexpr double kRpeSpanTolerance = 0.05;

// The rotation angle of R [rad], accurate for small angles too.
double rotation_angle(const Eigen::Matrix3d& R) {
  const Eigen::Quaterniond q(R);
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}

}  // namespace

SE3d align_rigid(std::span<const Eigen::Vector3d> from, std::span<const Eigen::Vector3d> to) {
  if (from.size() != to.size()) {
    throw std::invalid_argument("align_rigid: " + std::to_string(from.size()) +
                                " points to map onto " + std::to_string(to.size()));
  }
  if (from.size() < 3) {
    throw std::invalid_argument("align_rigid: needs at least 3 point pairs, got " +
                                std::to_string(from.size()));
  }
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(from.size()));
  Eigen::Matrix3Xd dst(3, static_cast<Eigen::Index>(to.size()));
  for (std::size_t i = 0; i < from.size(); ++i) {
    src.col(static_cast<Eigen::Index>(i)) = from[i];
    dst.col(static_cast<Eigen::Index>(i)) = to[i];
  }
  SE3d T = SE3d::Identity();
  T.matrix() = Eigen::umeyama(src, dst, /*with_scaling=*/false);
  return T;
}

TrajectoryErrors evaluate_trajectory(std::span<const StampedPose> est,
                                     std::span<const StampedPose> gt,
                                     const TrajectoryEvalOptions& options) {
  if (options.max_dt_ns < 0 || !(options.rpe_delta_s > 0)) {
    throw std::invalid_argument("evaluate_trajectory: needs max_dt_ns >= 0 and rpe_delta_s > 0");
  }
  if (!sorted(est) || !sorted(gt)) {
    throw std::invalid_argument("evaluate_trajectory: poses must be sorted by time");
  }
  std::vector<TimeNs> t_ns;
  std::vector<SE3d> e, g;
  for (const StampedPose& p : est) {
    if (const auto T = interpolate(gt, p.t_ns, options.max_dt_ns)) {
      t_ns.push_back(p.t_ns);
      e.push_back(p.T_world_body);
      g.push_back(*T);
    }
  }
  if (e.size() < 3) {
    throw std::invalid_argument("evaluate_trajectory: only " + std::to_string(e.size()) + " of " +
                                std::to_string(est.size()) +
                                " estimates have ground truth at their time, need 3");
  }
  TrajectoryErrors out;
  out.matched = e.size();
  std::vector<Eigen::Vector3d> p_est(e.size()), p_gt(g.size());
  for (std::size_t i = 0; i < e.size(); ++i) {
    p_est[i] = e[i].translation();
    p_gt[i] = g[i].translation();
    if (i > 0) out.path_length_m += (p_gt[i] - p_gt[i - 1]).norm();
  }
  if (options.align) out.T_gt_est = align_rigid(p_est, p_gt);
  double sum2 = 0;
  for (std::size_t i = 0; i < e.size(); ++i) {
    const double err = (out.T_gt_est * p_est[i] - p_gt[i]).norm();
    sum2 += err * err;
    out.ate_max_m = std::max(out.ate_max_m, err);
  }
  out.ate_rmse_m = std::sqrt(sum2 / static_cast<double>(e.size()));

  const auto delta_ns = static_cast<double>(s_to_ns(options.rpe_delta_s));
  double trans2 = 0, rot2 = 0, span_sum = 0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < e.size(); ++i) {
    // The later pose whose span to i is nearest delta: j only moves forward as i does.
    j = std::max(j, i + 1);
    while (j + 1 < e.size() && std::abs(static_cast<double>(t_ns[j + 1] - t_ns[i]) - delta_ns) <=
                                   std::abs(static_cast<double>(t_ns[j] - t_ns[i]) - delta_ns)) {
      ++j;
    }
    if (j >= e.size()) break;
    const double span = static_cast<double>(t_ns[j] - t_ns[i]);
    if (std::abs(span - delta_ns) >= kRpeSpanTolerance * delta_ns) continue;
    const SE3d E = (g[i].inverse() * g[j]).inverse() * (e[i].inverse() * e[j]);
    trans2 += E.translation().squaredNorm();
    const double angle = rotation_angle(E.linear());
    rot2 += angle * angle;
    span_sum += span;
    ++out.rpe_pairs;
  }
  if (out.rpe_pairs > 0) {
    const auto n = static_cast<double>(out.rpe_pairs);
    out.rpe_trans_rmse_m = std::sqrt(trans2 / n);
    out.rpe_rot_rmse_deg = std::sqrt(rot2 / n) * 180.0 / std::numbers::pi;
    out.rpe_delta_s = span_sum / n * 1e-9;
  }
  return out;
}

}  // namespace wallar::dsp
