// SPDX-License-Identifier: Apache-2.0
/// @file visual_rotation.cpp
/// @brief Camera rotation between two images: ORB matches, bearings, RANSAC + Kabsch.
#include "wallar/dsp/imu/visual_rotation.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace wallar::dsp {
namespace {

cv::Mat wrap(const Image& img) {
  if (img.empty() || img.format() != PixelFormat::kGray8) {
    throw std::invalid_argument("visual rotation needs 8-bit gray images");
  }
  return cv::Mat(img.height(), img.width(), CV_8UC1, const_cast<std::uint8_t*>(img.data()),
                 static_cast<std::size_t>(img.stride_bytes()));
}

// R minimising sum w |b1 - R b0|^2 over the given indices (Kabsch, det +1).
Eigen::Matrix3d kabsch(const std::vector<Eigen::Vector3d>& b0,
                       const std::vector<Eigen::Vector3d>& b1,
                       const std::vector<std::size_t>& idx) {
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (const std::size_t i : idx) H += b1[i] * b0[i].transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

}  // namespace

std::optional<VisualRotation> camera_rotation_between(const Image& image0, const Image& image1,
                                                      const CameraCalibration& cam,
                                                      const VisualRotationParams& params) {
  const cv::Mat img0 = wrap(image0);
  const cv::Mat img1 = wrap(image1);
  // ORB matched both ways (features2d is in every build, including the arm64 cross-build).
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(params.max_corners);
  std::vector<cv::KeyPoint> k0, k1;
  cv::Mat d0, d1;
  orb->detectAndCompute(img0, cv::noArray(), k0, d0);
  orb->detectAndCompute(img1, cv::noArray(), k1, d1);
  if (k0.size() < params.min_inliers || k1.size() < params.min_inliers) return std::nullopt;
  std::vector<cv::DMatch> matches;
  cv::BFMatcher(cv::NORM_HAMMING, true).match(d0, d1, matches);
  std::vector<cv::Point2f> q0, q1;
  for (const cv::DMatch& m : matches) {
    q0.push_back(k0[static_cast<std::size_t>(m.queryIdx)].pt);
    q1.push_back(k1[static_cast<std::size_t>(m.trainIdx)].pt);
  }
  VisualRotation out;
  out.tracked = q0.size();
  if (q0.size() < params.min_inliers) return std::nullopt;
  const cv::Matx33d K(cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0);
  const cv::Mat dist = cam.distortion.empty() ? cv::Mat() : cv::Mat(cam.distortion);
  std::vector<cv::Point2f> n0, n1;
  cv::undistortPoints(q0, n0, K, dist);
  cv::undistortPoints(q1, n1, K, dist);
  std::vector<Eigen::Vector3d> b0(n0.size()), b1(n1.size());
  for (std::size_t i = 0; i < n0.size(); ++i) {
    b0[i] = Eigen::Vector3d(n0[i].x, n0[i].y, 1.0).normalized();
    b1[i] = Eigen::Vector3d(n1[i].x, n1[i].y, 1.0).normalized();
  }
  const double threshold = params.inlier_threshold_px / cam.fx;  // chord ~ angle [rad]
  std::uint64_t state = params.seed * 0x9E3779B97F4A7C15ULL + 1;
  auto pick = [&state](std::size_t n) {  // deterministic on every platform
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<std::size_t>((state >> 33) % n);
  };
  std::vector<std::size_t> best, inliers;
  for (int round = 0; round < params.ransac_rounds; ++round) {
    const std::size_t i = pick(b0.size());
    const std::size_t j = pick(b0.size());
    if (i == j || b0[i].cross(b0[j]).norm() < 0.05) continue;  // two distinct directions
    const Eigen::Matrix3d R = kabsch(b0, b1, {i, j});
    inliers.clear();
    for (std::size_t k = 0; k < b0.size(); ++k) {
      if ((b1[k] - R * b0[k]).norm() < threshold) inliers.push_back(k);
    }
    if (inliers.size() > best.size()) best = inliers;
  }
  if (best.size() < params.min_inliers) return std::nullopt;
  Eigen::Matrix3d R_cam1_cam0 = kabsch(b0, b1, best);
  // One refit on the inliers of the refined rotation.
  inliers.clear();
  for (std::size_t k = 0; k < b0.size(); ++k) {
    if ((b1[k] - R_cam1_cam0 * b0[k]).norm() < threshold) inliers.push_back(k);
  }
  if (inliers.size() >= params.min_inliers) R_cam1_cam0 = kabsch(b0, b1, inliers);
  double sq = 0.0;
  for (const std::size_t k : inliers) sq += (b1[k] - R_cam1_cam0 * b0[k]).squaredNorm();
  out.inliers = inliers.size();
  out.rms_error_px =
      std::sqrt(sq / static_cast<double>(std::max<std::size_t>(inliers.size(), 1))) * cam.fx;
  const Eigen::AngleAxisd aa(R_cam1_cam0.transpose());  // R_cam0_cam1
  out.rotvec_cam0_cam1 = aa.angle() * aa.axis();
  if (out.inliers < params.min_inliers) return std::nullopt;
  return out;
}

}  // namespace wallar::dsp
