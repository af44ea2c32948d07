// SPDX-License-Identifier: Apache-2.0
/// @file bundle_adjustment.cpp
/// @brief Stereo bundle adjustment: Huber-weighted Gauss-Newton normal equations, points
/// eliminated by the Schur complement, Levenberg-Marquardt damping with Nielsen's update.
///
/// Unknowns: a twist xi_c (6) per free keyframe, applied on the left (T <- exp(xi) T), and an
/// additive dp (3) per free point. Normal equations, g the gradient of the robust cost:
///   [ U   W ] [dc]   [ -g_c ]      U: 6x6 block-diagonal (cameras)
///   [ W^T V ] [dp] = [ -g_p ]      V: 3x3 block-diagonal (points), W: 6x3 per observation
/// Points are eliminated: (U - W V^-1 W^T) dc = -g_c + W V^-1 g_p, then dp = V^-1 (-g_p - W^T dc).
#include "wallar/dsp/tracking/bundle_adjustment.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <stdexcept>
#include <string>

namespace wallar::dsp {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat63 = Eigen::Matrix<double, 6, 3>;

constexpr double kMinDepth_m = 1e-6;
constexpr double kMinDiagonal = 1e-6;  // damping floor for degenerate diagonal entries
constexpr double kMaxLambda = 1e16;    // beyond this no step can make progress

// --- Input checks -------------------------------------------------------------------------------

void validate(const StereoIntrinsics& K, const std::vector<BaKeyframe>& keyframes,
              const std::vector<BaPoint>& points, std::span<const BaObservation> observations) {
  if (!(K.f_px > 0) || !std::isfinite(K.f_px) || !std::isfinite(K.cx_px) ||
      !std::isfinite(K.cy_px) || !std::isfinite(K.baseline_m)) {
    throw std::invalid_argument("bundle_adjust: intrinsics need a finite f_px > 0");
  }
  if (std::none_of(keyframes.begin(), keyframes.end(),
                   [](const BaKeyframe& k) { return k.fixed; })) {
    throw std::invalid_argument(
        "bundle_adjust: no fixed keyframe; fix at least one to hold the gauge");
  }
  const auto n_kf = static_cast<int>(keyframes.size());
  const auto n_pt = static_cast<int>(points.size());
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const BaObservation& o = observations[i];
    const std::string name = "bundle_adjust: observation " + std::to_string(i);
    if (o.keyframe < 0 || o.keyframe >= n_kf) {
      throw std::invalid_argument(name + " has keyframe index " + std::to_string(o.keyframe) +
                                  " outside [0, " + std::to_string(n_kf) + ")");
    }
    if (o.point < 0 || o.point >= n_pt) {
      throw std::invalid_argument(name + " has point index " + std::to_string(o.point) +
                                  " outside [0, " + std::to_string(n_pt) + ")");
    }
    if (!std::isfinite(o.u_px) || !std::isfinite(o.v_px) || std::isinf(o.u_right_px)) {
      throw std::invalid_argument(name + " has a non-finite pixel");
    }
  }
}

// --- Robust loss --------------------------------------------------------------------------------

// Huber on the observation's error e = |r|: rho(e^2) = e^2 inside k, 2 k e - k^2 outside.
// IRLS weight w = rho'(e^2) = min(1, k / e): the gradient of 0.5 rho is w J^T r.
struct Huber {
  double k;
  [[nodiscard]] double cost(double e) const { return e <= k ? e * e : 2.0 * k * e - k * k; }
  [[nodiscard]] double weight(double e) const { return e <= k ? 1.0 : k / e; }
};

// --- Problem layout -----------------------------------------------------------------------------

// Which keyframes are unknowns, and the observations grouped by point (CSR).
struct Layout {
  std::vector<int> cam_of_keyframe;  // -1 for fixed keyframes, else 0..n_cams-1
  int n_cams = 0;
  std::vector<std::size_t> point_begin;  // obs of point p: obs_by_point[point_begin[p] ..
  std::vector<int> obs_by_point;         //                              point_begin[p + 1])
};

Layout make_layout(const std::vector<BaKeyframe>& keyframes, std::size_t n_points,
                   std::span<const BaObservation> observations) {
  Layout L;
  L.cam_of_keyframe.reserve(keyframes.size());
  for (const BaKeyframe& k : keyframes) L.cam_of_keyframe.push_back(k.fixed ? -1 : L.n_cams++);
  L.point_begin.assign(n_points + 1, 0);
  for (const BaObservation& o : observations)
    ++L.point_begin[static_cast<std::size_t>(o.point) + 1];
  for (std::size_t p = 0; p < n_points; ++p) L.point_begin[p + 1] += L.point_begin[p];
  L.obs_by_point.resize(observations.size());
  std::vector<std::size_t> next(L.point_begin.begin(), L.point_begin.end() - 1);
  for (std::size_t i = 0; i < observations.size(); ++i) {
    L.obs_by_point[next[static_cast<std::size_t>(observations[i].point)]++] = static_cast<int>(i);
  }
  return L;
}

// --- Projection ---------------------------------------------------------------------------------

// Residual of `obs` for a point already in camera coordinates; false behind the camera.
bool residual_in_camera(const StereoIntrinsics& K, const Eigen::Vector3d& p_cam,
                        const BaObservation& obs, Eigen::Vector3d& r, int& rows) {
  const double Z = p_cam.z();
  if (!(Z > kMinDepth_m)) return false;
  const double inv_z = 1.0 / Z;
  r.x() = K.f_px * p_cam.x() * inv_z + K.cx_px - obs.u_px;
  r.y() = K.f_px * p_cam.y() * inv_z + K.cy_px - obs.v_px;
  const bool stereo = !std::isnan(obs.u_right_px);
  // Right camera = left shifted by +b along x: X_right = X - b.
  r.z() = stereo ? K.f_px * (p_cam.x() - K.baseline_m) * inv_z + K.cx_px - obs.u_right_px : 0.0;
  rows = stereo ? 3 : 2;
  r /= obs.sigma_px;  // in units of the observation's noise
  return true;
}

// Robust cost of the current state and the observations in front of their camera.
struct Evaluation {
  double cost = 0;
  std::size_t used = 0, outliers = 0;
};

Evaluation evaluate(const StereoIntrinsics& K, const std::vector<BaKeyframe>& keyframes,
                    const std::vector<BaPoint>& points, std::span<const BaObservation> observations,
                    const Huber& huber) {
  Evaluation ev;
  for (const BaObservation& o : observations) {
    const Eigen::Vector3d p_cam = keyframes[static_cast<std::size_t>(o.keyframe)].T_cam_world *
                                  points[static_cast<std::size_t>(o.point)].p_world;
    Eigen::Vector3d r;
    int rows = 0;
    if (!residual_in_camera(K, p_cam, o, r, rows)) continue;
    const double e = r.norm();
    ev.cost += 0.5 * huber.cost(e);
    ++ev.used;
    if (e > 3.0 * huber.k) ++ev.outliers;
  }
  return ev;
}

// --- Normal equations ---------------------------------------------------------------------------

struct NormalEquations {
  std::vector<Mat6> U;             // per free camera: sum w Jc^T Jc
  std::vector<Vec6> g_cam;         //                  sum w Jc^T r
  std::vector<Eigen::Matrix3d> V;  // per point:       sum w Jp^T Jp
  std::vector<Eigen::Vector3d> g_point;
  std::vector<Mat63> W;          // per observation: w Jc^T Jp (camera and point both free)
  std::vector<char> obs_used;    // observation in front of its camera
  std::vector<char> point_free;  // point is an unknown in this iteration
  double cost = 0;
  std::size_t used = 0;
};

/// The pose prior of keyframe k: its error xi (T = exp(xi) T0, left perturbation, first
/// order) and per-coordinate information.
bool pose_prior(const BaKeyframe& k, const SE3d& T0, Vec6& xi, Vec6& info) {
  if (!(k.prior_sigma_m > 0.0) || !(k.prior_sigma_rad > 0.0)) return false;
  const SE3d d = k.T_cam_world * T0.inverse();
  const Eigen::AngleAxisd aa(d.linear());
  xi.head<3>() = d.translation();
  xi.tail<3>() = aa.angle() * aa.axis();
  info.head<3>().setConstant(1.0 / (k.prior_sigma_m * k.prior_sigma_m));
  info.tail<3>().setConstant(1.0 / (k.prior_sigma_rad * k.prior_sigma_rad));
  return true;
}

double prior_cost(const std::vector<BaKeyframe>& keyframes, const std::vector<SE3d>& initial) {
  double cost = 0.0;
  for (std::size_t k = 0; k < keyframes.size(); ++k) {
    Vec6 xi, info;
    if (keyframes[k].fixed || !pose_prior(keyframes[k], initial[k], xi, info)) continue;
    cost += 0.5 * xi.dot(info.cwiseProduct(xi));
  }
  return cost;
}

NormalEquations linearize(const StereoIntrinsics& K, const std::vector<BaKeyframe>& keyframes,
                          const std::vector<BaPoint>& points,
                          std::span<const BaObservation> observations, const Layout& L,
                          const Huber& huber, const std::vector<SE3d>& initial) {
  NormalEquations ne;
  ne.U.assign(static_cast<std::size_t>(L.n_cams), Mat6::Zero());
  ne.g_cam.assign(static_cast<std::size_t>(L.n_cams), Vec6::Zero());
  ne.V.assign(points.size(), Eigen::Matrix3d::Zero());
  ne.g_point.assign(points.size(), Eigen::Vector3d::Zero());
  ne.W.assign(observations.size(), Mat63::Zero());
  ne.obs_used.assign(observations.size(), 0);
  std::vector<int> rows_of_point(points.size(), 0);

  BaLinearization lin;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const BaObservation& o = observations[i];
    const auto k = static_cast<std::size_t>(o.keyframe);
    const auto p = static_cast<std::size_t>(o.point);
    if (!linearize_observation(K, keyframes[k].T_cam_world, points[p].p_world, o, lin)) continue;
    const double e = lin.residual_px.norm();
    const double w = huber.weight(e);
    ne.cost += 0.5 * huber.cost(e);
    ++ne.used;
    ne.obs_used[i] = 1;
    rows_of_point[p] += lin.rows;

    const Eigen::Matrix<double, 6, 3> wJcT = w * lin.J_pose.transpose();
    const int c = L.cam_of_keyframe[k];
    if (c >= 0) {
      ne.U[static_cast<std::size_t>(c)].noalias() += wJcT * lin.J_pose;
      ne.g_cam[static_cast<std::size_t>(c)].noalias() += wJcT * lin.residual_px;
      ne.W[i].noalias() = wJcT * lin.J_point;
    }
    ne.V[p].noalias() += w * lin.J_point.transpose() * lin.J_point;
    ne.g_point[p].noalias() += w * lin.J_point.transpose() * lin.residual_px;
  }
  for (std::size_t k = 0; k < keyframes.size(); ++k) {
    const int c = L.cam_of_keyframe[k];
    Vec6 xi, info;
    if (c < 0 || !pose_prior(keyframes[k], initial[k], xi, info)) continue;
    ne.U[static_cast<std::size_t>(c)].diagonal() += info;
    ne.g_cam[static_cast<std::size_t>(c)] += info.cwiseProduct(xi);
    ne.cost += 0.5 * xi.dot(info.cwiseProduct(xi));
  }
  ne.point_free.resize(points.size());
  for (std::size_t p = 0; p < points.size(); ++p) {
    ne.point_free[p] = static_cast<char>(!points[p].fixed && rows_of_point[p] >= 2);
  }
  return ne;
}

// --- Damped solve -------------------------------------------------------------------------------

struct Step {
  std::vector<Vec6> d_cam;
  std::vector<Eigen::Vector3d> d_point;  // zero for points that are not unknowns
  double predicted_decrease = 0;         // of the quadratic model
  bool ok = false;
};

// Marquardt damping: H_ii += lambda * max(H_ii, floor). Returns the added diagonal.
template <int N>
Eigen::Matrix<double, N, 1> damp(Eigen::Matrix<double, N, N>& H, double lambda) {
  const Eigen::Matrix<double, N, 1> d = lambda * H.diagonal().cwiseMax(kMinDiagonal);
  H.diagonal() += d;
  return d;
}

// Eliminates point p from the reduced camera system S dc = rhs (lower triangle of S filled).
// Stores V_p^-1 for the back-substitution; false when the damped V_p is not positive definite
// (then the point is held fixed for this step).
bool eliminate_point(const NormalEquations& ne, const Layout& L,
                     std::span<const BaObservation> observations, std::size_t p, double lambda,
                     Eigen::MatrixXd& S, Eigen::VectorXd& rhs, Eigen::Matrix3d& V_inv,
                     Eigen::Vector3d& damping) {
  Eigen::Matrix3d Vd = ne.V[p];
  damping = damp<3>(Vd, lambda);
  const Eigen::LLT<Eigen::Matrix3d> llt(Vd);
  if (llt.info() != Eigen::Success) return false;
  V_inv = llt.solve(Eigen::Matrix3d::Identity());
  if (!V_inv.allFinite()) return false;

  for (std::size_t a = L.point_begin[p]; a < L.point_begin[p + 1]; ++a) {
    const auto i = static_cast<std::size_t>(L.obs_by_point[a]);
    const int ci = L.cam_of_keyframe[static_cast<std::size_t>(observations[i].keyframe)];
    if (!ne.obs_used[i] || ci < 0) continue;
    const Mat63 WVinv = ne.W[i] * V_inv;
    rhs.segment<6>(6 * ci).noalias() += WVinv * ne.g_point[p];
    for (std::size_t b = L.point_begin[p]; b < L.point_begin[p + 1]; ++b) {
      const auto j = static_cast<std::size_t>(L.obs_by_point[b]);
      const int cj = L.cam_of_keyframe[static_cast<std::size_t>(observations[j].keyframe)];
      if (!ne.obs_used[j] || cj < 0 || cj > ci) continue;  // lower triangle only
      S.block<6, 6>(6 * ci, 6 * cj).noalias() -= WVinv * ne.W[j].transpose();
    }
  }
  return true;
}

Step solve(const NormalEquations& ne, const Layout& L, std::span<const BaObservation> observations,
           double lambda) {
  const std::size_t n_points = ne.V.size();
  const auto n_cams = static_cast<std::size_t>(L.n_cams);
  Step step;
  step.d_cam.assign(n_cams, Vec6::Zero());
  step.d_point.assign(n_points, Eigen::Vector3d::Zero());

  // Reduced camera system, starting from the damped U blocks and -g_c.
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(6 * L.n_cams, 6 * L.n_cams);
  Eigen::VectorXd rhs(6 * L.n_cams);
  std::vector<Vec6> cam_damping(n_cams);
  for (std::size_t c = 0; c < n_cams; ++c) {
    Mat6 Ud = ne.U[c];
    cam_damping[c] = damp<6>(Ud, lambda);
    S.block<6, 6>(6 * static_cast<Eigen::Index>(c), 6 * static_cast<Eigen::Index>(c)) = Ud;
    rhs.segment<6>(6 * static_cast<Eigen::Index>(c)) = -ne.g_cam[c];
  }
  std::vector<Eigen::Matrix3d> V_inv(n_points);
  std::vector<Eigen::Vector3d> point_damping(n_points, Eigen::Vector3d::Zero());
  std::vector<char> solved(n_points, 0);
  for (std::size_t p = 0; p < n_points; ++p) {
    if (!ne.point_free[p]) continue;
    solved[p] = static_cast<char>(
        eliminate_point(ne, L, observations, p, lambda, S, rhs, V_inv[p], point_damping[p]));
  }

  // Cameras: dense LDLT of the (lower triangle of the) symmetric reduced system.
  Eigen::VectorXd dc = Eigen::VectorXd::Zero(6 * L.n_cams);
  if (L.n_cams > 0) {
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(S);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return step;
    dc = ldlt.solve(rhs);
    if (!dc.allFinite()) return step;
  }
  for (std::size_t c = 0; c < n_cams; ++c) {
    step.d_cam[c] = dc.segment<6>(6 * static_cast<Eigen::Index>(c));
    // Predicted decrease of the quadratic model: 0.5 d^T (lambda D d - g).
    step.predicted_decrease +=
        0.5 * step.d_cam[c].dot(cam_damping[c].cwiseProduct(step.d_cam[c]) - ne.g_cam[c]);
  }

  // Points: back-substitution dp = V^-1 (-g_p - sum_obs W^T dc).
  for (std::size_t p = 0; p < n_points; ++p) {
    if (!solved[p]) continue;
    Eigen::Vector3d b = -ne.g_point[p];
    for (std::size_t a = L.point_begin[p]; a < L.point_begin[p + 1]; ++a) {
      const auto i = static_cast<std::size_t>(L.obs_by_point[a]);
      const int c = L.cam_of_keyframe[static_cast<std::size_t>(observations[i].keyframe)];
      if (ne.obs_used[i] && c >= 0) b.noalias() -= ne.W[i].transpose() * dc.segment<6>(6 * c);
    }
    step.d_point[p] = V_inv[p] * b;
    step.predicted_decrease +=
        0.5 * step.d_point[p].dot(point_damping[p].cwiseProduct(step.d_point[p]) - ne.g_point[p]);
  }
  step.ok = std::isfinite(step.predicted_decrease);
  return step;
}

// Candidate state: free keyframes moved by exp(dxi) on the left, free points by dp.
void apply(const Step& step, const Layout& L, std::vector<BaKeyframe>& keyframes,
           std::vector<BaPoint>& points) {
  for (std::size_t k = 0; k < keyframes.size(); ++k) {
    const int c = L.cam_of_keyframe[k];
    if (c < 0) continue;
    SE3d T = orthonormalised(se3_exp(step.d_cam[static_cast<std::size_t>(c)]) *
                             keyframes[k].T_cam_world);
    T.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();  // no drift
    keyframes[k].T_cam_world = T;
  }
  for (std::size_t p = 0; p < points.size(); ++p) points[p].p_world += step.d_point[p];
}

}  // namespace

// --- Building blocks ----------------------------------------------------------------------------

bool linearize_observation(const StereoIntrinsics& K, const SE3d& T_cam_world,
                           const Eigen::Vector3d& p_world, const BaObservation& obs,
                           BaLinearization& out) {
  // Camera coordinates: p_c = R p_w + t.
  const Eigen::Vector3d p_cam = T_cam_world * p_world;
  Eigen::Vector3d r;
  int rows = 0;
  if (!residual_in_camera(K, p_cam, obs, r, rows)) return false;
  const double X = p_cam.x(), Y = p_cam.y(), Z = p_cam.z();
  const double fz = K.f_px / Z, fz2 = K.f_px / (Z * Z);

  // Projection Jacobian d(u_l, v, u_r)/d(X, Y, Z):
  //   u_l = f X/Z + cx      -> [f/Z, 0, -f X/Z^2]
  //   v   = f Y/Z + cy      -> [0, f/Z, -f Y/Z^2]
  //   u_r = f (X-b)/Z + cx  -> [f/Z, 0, -f (X-b)/Z^2]
  Eigen::Matrix3d J_proj;
  J_proj << fz, 0, -X * fz2, 0, fz, -Y * fz2, fz, 0, -(X - K.baseline_m) * fz2;
  if (rows == 2) J_proj.row(2).setZero();
  J_proj /= obs.sigma_px;

  // Left perturbation T <- exp(xi) T, xi = (v, w): p_c <- p_c + w x p_c + v to first order,
  // so dp_c/dxi = [I | -[p_c]x]. The point enters through R: dp_c/dp_w = R.
  Eigen::Matrix<double, 3, 6> dpc_dxi;
  dpc_dxi << Eigen::Matrix3d::Identity(), -skew(p_cam);
  out.residual_px = r;
  out.J_pose.noalias() = J_proj * dpc_dxi;
  out.J_point.noalias() = J_proj * T_cam_world.linear();
  out.rows = rows;
  return true;
}

// --- Levenberg-Marquardt ------------------------------------------------------------------------

BaResult bundle_adjust(const StereoIntrinsics& K, std::vector<BaKeyframe>& keyframes,
                       std::vector<BaPoint>& points, std::span<const BaObservation> observations,
                       const BaOptions& options) {
  validate(K, keyframes, points, observations);
  const Layout L = make_layout(keyframes, points.size(), observations);
  const Huber huber{options.huber_px};

  BaResult result;
  std::vector<SE3d> initial;
  initial.reserve(keyframes.size());
  for (const BaKeyframe& k : keyframes) initial.push_back(k.T_cam_world);
  NormalEquations ne = linearize(K, keyframes, points, observations, L, huber, initial);
  result.initial_cost = ne.cost;
  double lambda = options.initial_lambda;
  double nu = 2.0;  // Nielsen's growth factor for consecutive rejections
  std::vector<BaKeyframe> kf_try;
  std::vector<BaPoint> pt_try;

  bool stale = false;  // state moved since `ne` was built
  while (result.iterations < options.max_iterations) {
    if (stale) {
      ne = linearize(K, keyframes, points, observations, L, huber, initial);
      stale = false;
    }
    if (ne.cost <= 0.0) {
      result.converged = true;
      break;
    }
    const Step step = solve(ne, L, observations, lambda);
    ++result.iterations;
    if (step.ok && step.predicted_decrease <= options.min_relative_decrease * ne.cost) {
      result.converged = true;  // even the model expects no worthwhile decrease
      break;
    }
    bool accepted = false;
    double actual = 0.0;
    if (step.ok) {
      kf_try = keyframes;
      pt_try = points;
      apply(step, L, kf_try, pt_try);
      const Evaluation ev = evaluate(K, kf_try, pt_try, observations, huber);
      actual = ne.cost - (ev.cost + prior_cost(kf_try, initial));
      // A step that pushes points behind a camera drops terms: not comparable, reject it.
      accepted = actual > 0.0 && ev.used >= ne.used;
    }
    if (!accepted) {
      lambda *= nu;
      nu *= 2.0;
      if (lambda > kMaxLambda) break;
      continue;
    }
    // Nielsen: shrink lambda by up to 3x when the model predicted the decrease well.
    const double rho = actual / step.predicted_decrease;
    lambda *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
    nu = 2.0;
    keyframes.swap(kf_try);
    points.swap(pt_try);
    stale = true;
    if (actual / ne.cost < options.min_relative_decrease) {
      result.converged = true;
      break;
    }
  }
  const Evaluation final_eval = evaluate(K, keyframes, points, observations, huber);
  result.final_cost = final_eval.cost + prior_cost(keyframes, initial);
  result.outliers = final_eval.outliers;
  result.observations_used = final_eval.used;
  return result;
}

}  // namespace wallar::dsp
