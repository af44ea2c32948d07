// SPDX-License-Identifier: Apache-2.0
/// @file test_bundle_adjustment.cpp
/// @brief Stereo bundle adjustment on synthetic scenes: convergence from perturbed poses and
/// points, Huber against gross outliers, fixed keyframes, left-only observations, bad input, and
/// the analytic Jacobians against numerical differentiation.
///
/// Threading: test-thread only.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <unsupported/Eigen/MatrixFunctions>
#include <vector>

#include "tracking_support.hpp"
#include "wallar/dsp/tracking/bundle_adjustment.hpp"

namespace wallar::dsp {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

using test::Rng;

// 640x480 cameras (f of OpenCV's sample pair, docs/results.md) on a 12 cm baseline.
const StereoIntrinsics kRig{535.0, 320.0, 240.0, 0.12};

// T_cam_world of a camera at `center` looking at `target`, world y pointing down.
SE3d look_at(const Eigen::Vector3d& center, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - center).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  SE3d T_world_cam = SE3d::Identity();
  T_world_cam.linear().col(0) = x;
  T_world_cam.linear().col(1) = y;
  T_world_cam.linear().col(2) = z;
  T_world_cam.translation() = center;
  return T_world_cam.inverse();
}

struct Scene {
  std::vector<BaKeyframe> truth_kf;
  std::vector<BaPoint> truth_pt;
  std::vector<BaObservation> obs;
};

// `n_kf` keyframes on an 80 degree arc of radius 2 m around `n_pt` points in a 2 x 1.5 x 2 m
// box; every point seen inside the 640x480 image is observed with `noise_px` Gaussian noise.
Scene make_scene(Rng& rng, int n_kf, int n_pt, double noise_px, bool stereo) {
  Scene s;
  for (int k = 0; k < n_kf; ++k) {
    const double a = (-40.0 + 80.0 * k / (n_kf - 1)) * kDeg;
    const Eigen::Vector3d c(2.0 * std::sin(a), -0.3 + 0.1 * (k % 2), -2.0 * std::cos(a));
    s.truth_kf.push_back({look_at(c, Eigen::Vector3d(0, 0.2, 0)), false});
  }
  for (int p = 0; p < n_pt; ++p) {
    s.truth_pt.push_back(
        {Eigen::Vector3d(rng.uniform(-1, 1), rng.uniform(-0.75, 0.75), rng.uniform(-1, 1)), false});
  }
  for (int p = 0; p < n_pt; ++p) {
    for (int k = 0; k < n_kf; ++k) {
      const Eigen::Vector3d q = s.truth_kf[static_cast<std::size_t>(k)].T_cam_world *
                                s.truth_pt[static_cast<std::size_t>(p)].p_world;
      const double u = kRig.f_px * q.x() / q.z() + kRig.cx_px;
      const double v = kRig.f_px * q.y() / q.z() + kRig.cy_px;
      if (q.z() < 0.3 || u < 0 || u >= 640 || v < 0 || v >= 480) continue;
      const double ur = kRig.f_px * (q.x() - kRig.baseline_m) / q.z() + kRig.cx_px;
      BaObservation o{k, p, u + noise_px * rng.gaussian(), v + noise_px * rng.gaussian(), NAN};
      if (stereo) o.u_right_px = ur + noise_px * rng.gaussian();
      s.obs.push_back(o);
    }
  }
  return s;
}

// Poses moved by `trans_m` and `rot_rad` (random axes), points by `point_m`; fixed ones stay.
void perturb(Rng& rng, std::vector<BaKeyframe>& kfs, std::vector<BaPoint>& pts, double trans_m,
             double rot_rad, double point_m) {
  for (BaKeyframe& k : kfs) {
    if (k.fixed) continue;
    SE3d D = SE3d::Identity();
    D.linear() = Eigen::AngleAxisd(rot_rad, rng.direction()).toRotationMatrix();
    D.translation() = trans_m * rng.direction();
    k.T_cam_world = D * k.T_cam_world;
  }
  for (BaPoint& p : pts) {
    if (!p.fixed) p.p_world += point_m * rng.direction();
  }
}

struct PoseError {
  double trans_m = 0, rot_rad = 0;
};

// Camera-centre distance and rotation angle between an estimate and the truth.
PoseError pose_error(const SE3d& T_est, const SE3d& T_true) {
  const Eigen::Vector3d c_est = T_est.inverse().translation();
  const Eigen::Vector3d c_true = T_true.inverse().translation();
  const Eigen::AngleAxisd d(T_est.linear() * T_true.linear().transpose());
  return {(c_est - c_true).norm(), std::abs(d.angle())};
}

PoseError worst_pose_error(const std::vector<BaKeyframe>& est,
                           const std::vector<BaKeyframe>& truth) {
  PoseError worst;
  for (std::size_t k = 0; k < est.size(); ++k) {
    const PoseError e = pose_error(est[k].T_cam_world, truth[k].T_cam_world);
    worst.trans_m = std::max(worst.trans_m, e.trans_m);
    worst.rot_rad = std::max(worst.rot_rad, e.rot_rad);
  }
  return worst;
}

// Plain (not robust) sum of squared reprojection errors [px^2].
double squared_error(const std::vector<BaKeyframe>& kfs, const std::vector<BaPoint>& pts,
                     const std::vector<BaObservation>& obs) {
  double sum = 0;
  for (const BaObservation& o : obs) {
    BaLinearization lin;
    if (linearize_observation(kRig, kfs[static_cast<std::size_t>(o.keyframe)].T_cam_world,
                              pts[static_cast<std::size_t>(o.point)].p_world, o, lin)) {
      sum += lin.residual_px.squaredNorm();
    }
  }
  return sum;
}

TEST(BundleAdjustment, ConvergesFromPerturbedPosesAndPoints) {
  Rng rng(7);
  Scene s = make_scene(rng, 8, 300, 0.5, true);
  std::vector<BaKeyframe> kfs = s.truth_kf;
  std::vector<BaPoint> pts = s.truth_pt;
  kfs[0].fixed = true;
  perturb(rng, kfs, pts, 0.02, 1.0 * kDeg, 0.05);
  ASSERT_GT(worst_pose_error(kfs, s.truth_kf).trans_m, 0.015);
  const double squared_before = squared_error(kfs, pts, s.obs);

  const BaResult r = bundle_adjust(kRig, kfs, pts, s.obs);
  const PoseError e = worst_pose_error(kfs, s.truth_kf);
  EXPECT_LT(e.trans_m, 0.003);
  EXPECT_LT(e.rot_rad, 0.1 * kDeg);
  // Squared error: down to the noise floor. The Huber cost is linear above 2 px, so its ratio is
  // about (mean initial error / noise): ~95x for these perturbations, asserted at 50x.
  EXPECT_GT(squared_before, 100.0 * squared_error(kfs, pts, s.obs));
  EXPECT_GT(r.initial_cost, 50.0 * r.final_cost);
  EXPECT_TRUE(r.converged);
  EXPECT_LE(r.iterations, 10);
  EXPECT_EQ(r.outliers, 0u);
  EXPECT_EQ(r.observations_used, s.obs.size());
  // Points seen by 3 or more keyframes: back near the truth (stereo depth noise ~1 cm at 2 m).
  std::vector<int> seen(pts.size(), 0);
  for (const BaObservation& o : s.obs) ++seen[static_cast<std::size_t>(o.point)];
  double sum_sq = 0;
  int n = 0;
  for (std::size_t p = 0; p < pts.size(); ++p) {
    if (seen[p] < 3) continue;
    sum_sq += (pts[p].p_world - s.truth_pt[p].p_world).squaredNorm();
    ++n;
  }
  ASSERT_GT(n, 250);
  EXPECT_LT(std::sqrt(sum_sq / n), 0.01);
}

TEST(BundleAdjustment, HuberKeepsPosesWithTenPercentGrossOutliers) {
  Rng rng(11);
  Scene s = make_scene(rng, 8, 300, 0.5, true);
  std::size_t n_bad = 0;
  for (BaObservation& o : s.obs) {
    if (rng.uniform() >= 0.1) continue;
    const double a = rng.uniform(0, 2 * kPi);  // 20 px off in a random image direction
    o.u_px += 20 * std::cos(a);
    o.u_right_px += 20 * std::cos(a);
    o.v_px += 20 * std::sin(a);
    ++n_bad;
  }
  ASSERT_GT(n_bad, s.obs.size() / 20);
  std::vector<BaKeyframe> kfs = s.truth_kf;
  std::vector<BaPoint> pts = s.truth_pt;
  kfs[0].fixed = true;
  perturb(rng, kfs, pts, 0.02, 1.0 * kDeg, 0.05);

  const BaResult r = bundle_adjust(kRig, kfs, pts, s.obs);
  const PoseError e = worst_pose_error(kfs, s.truth_kf);
  EXPECT_LT(e.trans_m, 0.01);
  EXPECT_LT(e.rot_rad, 0.3 * kDeg);
  EXPECT_LT(r.final_cost, r.initial_cost);
  // The gross errors stand out after the adjustment; the good ones do not.
  EXPECT_GT(r.outliers, n_bad * 8 / 10);
  EXPECT_LT(r.outliers, n_bad * 12 / 10);
}

TEST(BundleAdjustment, FixedKeyframesAndPointsDoNotMove) {
  Rng rng(3);
  Scene s = make_scene(rng, 6, 150, 0.5, true);
  std::vector<BaKeyframe> kfs = s.truth_kf;
  std::vector<BaPoint> pts = s.truth_pt;
  perturb(rng, kfs, pts, 0.02, 1.0 * kDeg, 0.05);  // fixed ones are wrong too: they must stay
  kfs[0].fixed = true;
  kfs[3].fixed = true;
  pts[5].fixed = true;
  const std::vector<BaKeyframe> before = kfs;
  const Eigen::Vector3d p5 = pts[5].p_world;

  const BaResult r = bundle_adjust(kRig, kfs, pts, s.obs);
  EXPECT_LT(r.final_cost, r.initial_cost);
  EXPECT_EQ(kfs[0].T_cam_world.matrix(), before[0].T_cam_world.matrix());
  EXPECT_EQ(kfs[3].T_cam_world.matrix(), before[3].T_cam_world.matrix());
  EXPECT_NE(kfs[1].T_cam_world.matrix(), before[1].T_cam_world.matrix());
  EXPECT_EQ(pts[5].p_world, p5);
}

TEST(BundleAdjustment, ThrowsWithoutFixedKeyframeOrOnBadIndices) {
  Rng rng(5);
  Scene s = make_scene(rng, 4, 20, 0.0, true);
  std::vector<BaKeyframe> kfs = s.truth_kf;
  std::vector<BaPoint> pts = s.truth_pt;
  try {
    bundle_adjust(kRig, kfs, pts, s.obs);
    FAIL() << "no fixed keyframe accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no fixed keyframe"), std::string::npos) << e.what();
  }
  kfs[0].fixed = true;
  for (const auto& [field, value] : {std::pair{0, 4}, std::pair{0, -1}, std::pair{1, 20}}) {
    std::vector<BaObservation> bad = s.obs;
    (field == 0 ? bad[5].keyframe : bad[5].point) = value;
    try {
      bundle_adjust(kRig, kfs, pts, bad);
      FAIL() << "bad index accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("observation 5 "), std::string::npos) << e.what();
    }
  }
  std::vector<BaObservation> bad = s.obs;
  bad[2].v_px = NAN;
  EXPECT_THROW(bundle_adjust(kRig, kfs, pts, bad), std::invalid_argument);
  EXPECT_THROW(bundle_adjust(StereoIntrinsics{}, kfs, pts, s.obs), std::invalid_argument);
}

TEST(BundleAdjustment, LeftOnlyObservationsConvergeWithTwoFixedKeyframes) {
  Rng rng(13);
  Scene s = make_scene(rng, 8, 300, 0.5, false);
  std::vector<BaKeyframe> kfs = s.truth_kf;
  std::vector<BaPoint> pts = s.truth_pt;
  kfs[0].fixed = true;  // two fixed keyframes: gauge and scale
  kfs[7].fixed = true;
  perturb(rng, kfs, pts, 0.02, 1.0 * kDeg, 0.05);
  const double squared_before = squared_error(kfs, pts, s.obs);

  BaOptions options;
  options.max_iterations = 20;
  const BaResult r = bundle_adjust(kRig, kfs, pts, s.obs, options);
  EXPECT_TRUE(r.converged);
  EXPECT_GT(squared_before, 100.0 * squared_error(kfs, pts, s.obs));
  EXPECT_GT(r.initial_cost, 50.0 * r.final_cost);
  const PoseError e = worst_pose_error(kfs, s.truth_kf);
  EXPECT_LT(e.trans_m, 0.005);
  EXPECT_LT(e.rot_rad, 0.1 * kDeg);
}

TEST(BundleAdjustment, UnusablePointsStayUnchangedAndNothingIsNaN) {
  Rng rng(17);
  Scene s = make_scene(rng, 5, 60, 0.5, true);
  std::vector<BaKeyframe> kfs = s.truth_kf;
  std::vector<BaPoint> pts = s.truth_pt;
  kfs[0].fixed = true;
  perturb(rng, kfs, pts, 0.01, 0.5 * kDeg, 0.03);
  std::vector<BaKeyframe> kfs_plain = kfs;
  std::vector<BaPoint> pts_plain = pts;
  bundle_adjust(kRig, kfs_plain, pts_plain, s.obs);

  // Point 60: behind every camera (no usable row). Point 61: one left-only observation (2 rows,
  // rank-deficient 3x3 block: it slides along its ray).
  const Eigen::Vector3d behind = kfs[2].T_cam_world.inverse() * Eigen::Vector3d(0, 0, -2);
  pts.push_back({behind, false});
  pts.push_back({Eigen::Vector3d(0.1, 0.1, 0.1), false});
  for (int k = 0; k < 5; ++k) s.obs.push_back({k, 60, 300, 200, 290});
  s.obs.push_back({1, 61, 330, 250, NAN});

  const BaResult r = bundle_adjust(kRig, kfs, pts, s.obs);
  EXPECT_LT(r.final_cost, r.initial_cost);
  EXPECT_EQ(r.observations_used, s.obs.size() - 5);
  EXPECT_EQ(pts[60].p_world, behind);
  for (const BaPoint& p : pts) EXPECT_TRUE(p.p_world.allFinite());
  for (const BaKeyframe& k : kfs) EXPECT_TRUE(k.T_cam_world.matrix().allFinite());
  // Neither point changes the poses: the same result as without them.
  EXPECT_LT(worst_pose_error(kfs, kfs_plain).trans_m, 1e-5);
}

TEST(BundleAdjustment, Se3ExpMatchesMatrixExponential) {
  Rng rng(19);
  for (double scale : {1e-9, 1e-3, 0.3, 2.5}) {
    Eigen::Matrix<double, 6, 1> xi;
    for (int i = 0; i < 6; ++i) xi[i] = scale * rng.uniform(-1, 1);
    Eigen::Matrix4d hat = Eigen::Matrix4d::Zero();  // [[w]x v; 0 0]
    hat.block<3, 3>(0, 0) << 0, -xi[5], xi[4], xi[5], 0, -xi[3], -xi[4], xi[3], 0;
    hat.block<3, 1>(0, 3) = xi.head<3>();
    const Eigen::Matrix4d expected = hat.exp();
    EXPECT_LT((se3_exp(xi).matrix() - expected).norm(), 1e-12) << "scale " << scale;
  }
}

TEST(BundleAdjustment, JacobiansMatchNumericalDifferentiation) {
  Rng rng(23);
  for (int trial = 0; trial < 20; ++trial) {
    const SE3d T = look_at(Eigen::Vector3d(rng.uniform(-2, 2), rng.uniform(-1, 1), -3),
                           Eigen::Vector3d(rng.uniform(-0.5, 0.5), 0, 0));
    const Eigen::Vector3d p(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    const bool stereo = trial % 2 == 0;
    const BaObservation o{0, 0, 300, 220, stereo ? 280.0 : NAN};
    BaLinearization lin;
    ASSERT_TRUE(linearize_observation(kRig, T, p, o, lin));
    EXPECT_EQ(lin.rows, stereo ? 3 : 2);

    const double h = 1e-6;
    auto residual = [&](const SE3d& Tx, const Eigen::Vector3d& px) {
      BaLinearization l;
      EXPECT_TRUE(linearize_observation(kRig, Tx, px, o, l));
      return Eigen::Vector3d(l.residual_px);
    };
    Eigen::Matrix<double, 3, 6> J_pose_num;
    for (int i = 0; i < 6; ++i) {
      Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
      d[i] = h;
      J_pose_num.col(i) = (residual(se3_exp(d) * T, p) - residual(se3_exp(-d) * T, p)) / (2 * h);
    }
    Eigen::Matrix3d J_point_num;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d d = h * Eigen::Vector3d::Unit(i);
      J_point_num.col(i) = (residual(T, p + d) - residual(T, p - d)) / (2 * h);
    }
    EXPECT_LT((lin.J_pose - J_pose_num).norm(), 1e-5 * lin.J_pose.norm()) << "trial " << trial;
    EXPECT_LT((lin.J_point - J_point_num).norm(), 1e-5 * lin.J_point.norm()) << "trial " << trial;
    if (!stereo) {
      EXPECT_EQ(lin.residual_px.z(), 0.0);
      EXPECT_TRUE(lin.J_pose.row(2).isZero());
    }
  }
  // Behind the camera: no linearization.
  BaLinearization lin;
  EXPECT_FALSE(linearize_observation(kRig, SE3d::Identity(), Eigen::Vector3d(0, 0, -1),
                                     BaObservation{}, lin));
}

}  // namespace
}  // namespace wallar::dsp
