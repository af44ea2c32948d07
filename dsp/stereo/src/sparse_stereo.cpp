// SPDX-License-Identifier: Apache-2.0
/// @file sparse_stereo.cpp
/// @brief Rectify, ORB, row-constrained matching, triangulation.
#include "wallar/dsp/stereo/sparse_stereo.hpp"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace wallar::dsp {
namespace {

cv::Mat wrap(const Image& img) {
  if (img.empty() || img.format() != PixelFormat::kGray8) {
    throw std::invalid_argument("sparse stereo needs 8-bit gray images");
  }
  // A header over the buffer: no pixel copy (OpenCV only reads it).
  return cv::Mat(img.height(), img.width(), CV_8UC1, const_cast<std::uint8_t*>(img.data()),
                 static_cast<std::size_t>(img.stride_bytes()));
}

cv::Matx33d intrinsics(const CameraCalibration& c) {
  return {c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0};
}

}  // namespace

SparseStereo::SparseStereo(const RigCalibration& rig, SparseStereoParams params) : params_(params) {
  const CameraCalibration& l = rig.cams[0];
  const CameraCalibration& r = rig.cams[1];
  if (l.distortion_model != "radial-tangential" || r.distortion_model != "radial-tangential") {
    throw std::invalid_argument("sparse stereo supports radial-tangential cameras only");
  }
  // OpenCV wants the transform from the left to the right camera: T_cam1_cam0.
  const SE3d T_cam1_cam0 = rig.T_cam0_cam1().inverse();
  cv::Matx33d R;
  cv::Vec3d t;
  for (int i = 0; i < 3; ++i) {
    t[i] = T_cam1_cam0.translation()[i];
    for (int j = 0; j < 3; ++j) R(i, j) = T_cam1_cam0.linear()(i, j);
  }
  const cv::Size size(l.width_px, l.height_px);
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(intrinsics(l), cv::Mat(l.distortion), intrinsics(r), cv::Mat(r.distortion),
                    size, R, t, R1, R2, P1, P2, Q, cv::CALIB_ZERO_DISPARITY, 0.0);
  cv::initUndistortRectifyMap(intrinsics(l), cv::Mat(l.distortion), R1, P1, size, CV_16SC2, map_lx_,
                              map_ly_);
  cv::initUndistortRectifyMap(intrinsics(r), cv::Mat(r.distortion), R2, P2, size, CV_16SC2, map_rx_,
                              map_ry_);
  R1_ = cv::Matx33d(R1);
  f_px_ = P1.at<double>(0, 0);
  cx_ = P1.at<double>(0, 2);
  cy_ = P1.at<double>(1, 2);
  baseline_m_ = -P2.at<double>(0, 3) / P2.at<double>(0, 0);
}

PointCloud SparseStereo::triangulate(const Image& left, const Image& right,
                                     SparseStereoStats* stats) {
  cv::Mat rl, rr;
  cv::remap(wrap(left), rl, map_lx_, map_ly_, cv::INTER_LINEAR);
  cv::remap(wrap(right), rr, map_rx_, map_ry_, cv::INTER_LINEAR);
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(params_.max_features);
  std::vector<cv::KeyPoint> kl, kr;
  cv::Mat dl, dr;
  orb->detectAndCompute(rl, cv::noArray(), kl, dl);
  orb->detectAndCompute(rr, cv::noArray(), kr, dr);
  SparseStereoStats st;
  st.features_left = kl.size();
  st.features_right = kr.size();
  PointCloud cloud;
  if (!dl.empty() && !dr.empty()) {
    cv::BFMatcher matcher(cv::NORM_HAMMING, /*crossCheck=*/true);
    std::vector<cv::DMatch> matches;
    matcher.match(dl, dr, matches);
    const cv::Matx33d R1t = R1_.t();
    for (const cv::DMatch& m : matches) {
      if (m.distance > params_.max_hamming) continue;
      const cv::Point2f pl = kl[static_cast<std::size_t>(m.queryIdx)].pt;
      const cv::Point2f pr = kr[static_cast<std::size_t>(m.trainIdx)].pt;
      if (std::abs(pl.y - pr.y) > params_.max_row_error_px) continue;
      const double disparity = pl.x - pr.x;
      if (!(disparity > 0.0)) continue;
      ++st.matches;
      const double z = f_px_ * baseline_m_ / disparity;
      if (z < params_.min_depth_m || z > params_.max_depth_m) continue;
      const cv::Vec3d p_rect((pl.x - cx_) * z / f_px_, (0.5 * (pl.y + pr.y) - cy_) * z / f_px_, z);
      const cv::Vec3d p = R1t * p_rect;  // back to the left camera's own frame
      cloud.push_back(Eigen::Vector3f(static_cast<float>(p[0]), static_cast<float>(p[1]),
                                      static_cast<float>(p[2])));
      ++st.triangulated;
    }
  }
  if (stats != nullptr) *stats = st;
  return cloud;
}

SparseMap build_sparse_map(SparseStereo& stereo, std::span<const StereoFrame> pairs, bool still) {
  SparseMap map;
  for (const StereoFrame& f : pairs) {
    const PointCloud c = stereo.triangulate(f.left.image, f.right.image);
    for (std::size_t i = 0; i < c.size(); ++i) map.points.push_back(c.point(i));
    ++map.pairs_used;
    if (!still) break;
  }
  return map;
}

}  // namespace wallar::dsp
