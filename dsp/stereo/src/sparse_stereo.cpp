// SPDX-License-Identifier: Apache-2.0
/// @file sparse_stereo.cpp
/// @brief Rectify, ORB, row-constrained matching, triangulation.
#include "wallar/dsp/stereo/sparse_stereo.hpp"

#include <cmath>
#include <opencv2/features2d.hpp>

namespace wallar::dsp {
SparseStereo::SparseStereo(const RigCalibration& rig, SparseStereoParams params)
    : params_(params), rectifier_(rig) {}

PointCloud SparseStereo::triangulate(const Image& left, const Image& right,
                                     SparseStereoStats* stats) {
  rectifier_.rectify(left, right);
  const cv::Mat& rl = rectifier_.left();
  const cv::Mat& rr = rectifier_.right();
  const double f_px = rectifier_.f_px(), cx = rectifier_.cx(), cy = rectifier_.cy();
  const double baseline_m = rectifier_.baseline_m();
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
    const cv::Matx33d R1t = rectifier_.R(0).t();
    for (const cv::DMatch& m : matches) {
      if (m.distance > params_.max_hamming) continue;
      const cv::Point2f pl = kl[static_cast<std::size_t>(m.queryIdx)].pt;
      const cv::Point2f pr = kr[static_cast<std::size_t>(m.trainIdx)].pt;
      if (std::abs(pl.y - pr.y) > params_.max_row_error_px) continue;
      const double disparity = pl.x - pr.x;
      if (!(disparity > 0.0)) continue;
      ++st.matches;
      const double z = f_px * baseline_m / disparity;
      if (z < params_.min_depth_m || z > params_.max_depth_m) continue;
      const cv::Vec3d p_rect((pl.x - cx) * z / f_px, (0.5 * (pl.y + pr.y) - cy) * z / f_px, z);
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
