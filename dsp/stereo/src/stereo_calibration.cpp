// SPDX-License-Identifier: Apache-2.0
/// @file stereo_calibration.cpp
/// @brief Chessboard calibration and the rectification check.
#include "wallar/dsp/stereo/stereo_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <stdexcept>

namespace wallar::dsp {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

std::vector<cv::Point3f> board_points(const ChessboardSpec& board) {
  std::vector<cv::Point3f> pts;
  for (int r = 0; r < board.inner_corners.height; ++r)
    for (int c = 0; c < board.inner_corners.width; ++c)
      pts.emplace_back(static_cast<float>(c * board.square_m),
                       static_cast<float>(r * board.square_m), 0.0f);
  return pts;
}

CameraCalibration to_camera(const cv::Matx33d& K, const cv::Mat& dist, cv::Size size, int index) {
  CameraCalibration c;
  c.name = "cam" + std::to_string(index);
  c.width_px = size.width;
  c.height_px = size.height;
  c.fx = K(0, 0);
  c.fy = K(1, 1);
  c.cx = K(0, 2);
  c.cy = K(1, 2);
  c.distortion_model = "radial-tangential";
  c.distortion.assign(4, 0.0);  // k1, k2, p1, p2
  for (int i = 0; i < 4 && i < static_cast<int>(dist.total()); ++i)
    c.distortion[static_cast<std::size_t>(i)] = dist.at<double>(i);
  return c;
}

}  // namespace

std::optional<std::vector<cv::Point2f>> find_chessboard(const cv::Mat& gray, cv::Size inner) {
  std::vector<cv::Point2f> corners;
  if (!cv::findChessboardCorners(gray, inner, corners,
                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE))
    return std::nullopt;
  cv::cornerSubPix(gray, corners, cv::Size(11, 11), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.01));
  return corners;
}

StereoCalibrationResult calibrate_stereo(std::span<const std::vector<cv::Point2f>> left,
                                         std::span<const std::vector<cv::Point2f>> right,
                                         cv::Size image_size, const ChessboardSpec& board,
                                         const StereoCalibrationParams& params) {
  if (left.size() != right.size())
    throw std::invalid_argument("calibrate_stereo: left and right view counts differ");
  const std::vector<cv::Point3f> object = board_points(board);
  std::vector<std::size_t> use(left.size());
  std::iota(use.begin(), use.end(), std::size_t{0});
  StereoCalibrationResult result;
  // Four distortion coefficients (k3 fixed at 0): the radtan model of EuRoC and Kalibr.
  const int mono_flags = cv::CALIB_FIX_K3;
  const int stereo_flags = cv::CALIB_USE_INTRINSIC_GUESS | cv::CALIB_FIX_K3;
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-6);
  for (int round = 0; round < 3; ++round) {
    if (use.size() < params.min_views)
      throw std::invalid_argument("calibration needs at least " + std::to_string(params.min_views) +
                                  " views, " + std::to_string(use.size()) + " usable");
    std::vector<std::vector<cv::Point3f>> obj(use.size(), object);
    std::vector<std::vector<cv::Point2f>> l, r;
    for (std::size_t i : use) {
      l.push_back(left[i]);
      r.push_back(right[i]);
    }
    std::array<cv::Mat, 2> K, D;
    std::vector<cv::Mat> rvecs, tvecs;
    result.mono_rms_px[0] =
        cv::calibrateCamera(obj, l, image_size, K[0], D[0], rvecs, tvecs, mono_flags, criteria);
    result.mono_rms_px[1] =
        cv::calibrateCamera(obj, r, image_size, K[1], D[1], rvecs, tvecs, mono_flags, criteria);
    cv::Mat R, T, E, F, per_view;
    result.rms_px = cv::stereoCalibrate(obj, l, r, K[0], D[0], K[1], D[1], image_size, R, T, E, F,
                                        per_view, stereo_flags, criteria);
    result.view_rms_px.clear();
    for (int i = 0; i < per_view.rows; ++i) {
      const double el = per_view.at<double>(i, 0), er = per_view.at<double>(i, 1);
      result.view_rms_px.push_back(std::sqrt(0.5 * (el * el + er * er)));
    }
    const double limit =
        std::max(params.reject_factor * median(result.view_rms_px), params.reject_floor_px);
    std::vector<std::size_t> keep;
    for (std::size_t k = 0; k < use.size(); ++k)
      if (result.view_rms_px[k] <= limit) keep.push_back(use[k]);
    // Solve again without the bad views, unless none is bad, too few would remain, or this was
    // the last round: then this round's solution (with its views) is the result.
    if (keep.size() == use.size() || keep.size() < params.min_views || round == 2) {
      for (std::size_t c = 0; c < 2; ++c)
        result.rig.cams[c] = to_camera(cv::Matx33d(K[c]), D[c], image_size, static_cast<int>(c));
      SE3d T_cam1_cam0 = SE3d::Identity();
      for (int i = 0; i < 3; ++i) {
        T_cam1_cam0.translation()[i] = T.at<double>(i);
        for (int j = 0; j < 3; ++j) T_cam1_cam0.linear()(i, j) = R.at<double>(i, j);
      }
      result.rig.cams[0].T_body_cam = SE3d::Identity();
      result.rig.cams[1].T_body_cam = T_cam1_cam0.inverse();
      result.baseline_m = T_cam1_cam0.translation().norm();
      result.views_used = use;
      break;
    }
    use = keep;
  }
  for (std::size_t i = 0; i < left.size(); ++i)
    if (std::find(result.views_used.begin(), result.views_used.end(), i) == result.views_used.end())
      result.views_rejected.push_back(i);
  return result;
}

void VerticalDisparity::add(const VerticalDisparity& o) {
  if (o.count == 0) return;
  const double n = static_cast<double>(count + o.count);
  mean_px = (mean_px * static_cast<double>(count) + o.mean_px * static_cast<double>(o.count)) / n;
  median_px =
      (median_px * static_cast<double>(count) + o.median_px * static_cast<double>(o.count)) / n;
  max_px = std::max(max_px, o.max_px);
  count += o.count;
}

VerticalDisparity vertical_disparity(const Rectifier& rectifier,
                                     std::span<const cv::Point2f> left_raw,
                                     std::span<const cv::Point2f> right_raw) {
  VerticalDisparity out;
  if (left_raw.empty() || left_raw.size() != right_raw.size()) return out;
  std::vector<cv::Point2f> l(left_raw.size()), r(right_raw.size());
  rectifier.rectify_points(0, left_raw, l);
  rectifier.rectify_points(1, right_raw, r);
  std::vector<double> dy(l.size());
  for (std::size_t i = 0; i < l.size(); ++i) dy[i] = std::abs(l[i].y - r[i].y);
  out.count = dy.size();
  out.mean_px = std::accumulate(dy.begin(), dy.end(), 0.0) / static_cast<double>(dy.size());
  out.max_px = *std::max_element(dy.begin(), dy.end());
  out.median_px = median(dy);
  return out;
}

VerticalDisparity vertical_disparity_of_features(const Rectifier& rectifier,
                                                 const cv::Mat& left_raw, const cv::Mat& right_raw,
                                                 int max_features) {
  // ORB finds correspondences at any disparity; mutual best matches that are also distinctive
  // (Lowe's ratio test both ways), since repeated texture such as a chessboard matches a
  // neighbouring square nearly as well as the right one.
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(max_features);
  std::vector<cv::KeyPoint> kl, kr;
  cv::Mat dl, dr;
  orb->detectAndCompute(left_raw, cv::noArray(), kl, dl);
  orb->detectAndCompute(right_raw, cv::noArray(), kr, dr);
  if (dl.empty() || dr.empty()) return {};
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> lr, rl;
  matcher.knnMatch(dl, dr, lr, 2);
  matcher.knnMatch(dr, dl, rl, 2);
  const auto distinct = [](const std::vector<cv::DMatch>& m) {
    return !m.empty() && (m.size() < 2 || m[0].distance < 0.8f * m[1].distance);
  };
  std::vector<cv::Point2f> pl, pr;
  for (const auto& m : lr) {
    if (!distinct(m) || m[0].distance > 50) continue;
    const auto& rev = rl[static_cast<std::size_t>(m[0].trainIdx)];
    if (!distinct(rev) || rev[0].trainIdx != m[0].queryIdx) continue;
    pl.push_back(kl[static_cast<std::size_t>(m[0].queryIdx)].pt);
    pr.push_back(kr[static_cast<std::size_t>(m[0].trainIdx)].pt);
  }
  if (pl.size() < 8) return {};
  // ORB's keypoints sit on the pixel grid of their pyramid level: refine each match to
  // sub-pixel with Lucas-Kanade seeded at the ORB match, keep it when tracking back returns
  // within 0.5 px of the left point.
  std::vector<cv::Point2f> fwd = pr, back = pl;
  std::vector<unsigned char> ok_fwd, ok_back;
  std::vector<float> err;
  const cv::Size window(11, 11);
  const cv::TermCriteria lk(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, 0.01);
  cv::calcOpticalFlowPyrLK(left_raw, right_raw, pl, fwd, ok_fwd, err, window, 1, lk,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  cv::calcOpticalFlowPyrLK(right_raw, left_raw, fwd, back, ok_back, err, window, 1, lk,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<cv::Point2f> tl, tr;
  for (std::size_t i = 0; i < pl.size(); ++i) {
    if (ok_fwd[i] == 0 || ok_back[i] == 0 || cv::norm(back[i] - pl[i]) > 0.5) continue;
    if (cv::norm(fwd[i] - pr[i]) > 2.0) continue;  // LK wandered off the ORB match
    tl.push_back(pl[i]);
    tr.push_back(fwd[i]);
  }
  pl = std::move(tl);
  pr = std::move(tr);
  if (pl.size() < 8) return {};
  // Gross mismatches out, judged by the data's own epipolar geometry: undistort with each
  // camera's intrinsics (keeping pixel units), then a RANSAC fundamental matrix at 1 px.
  std::vector<cv::Point2f> ul(pl.size()), ur(pr.size());
  cv::undistortPoints(pl, ul, rectifier.K(0), rectifier.dist(0), cv::noArray(), rectifier.K(0));
  cv::undistortPoints(pr, ur, rectifier.K(1), rectifier.dist(1), cv::noArray(), rectifier.K(1));
  std::vector<unsigned char> inlier;
  const cv::Mat F = cv::findFundamentalMat(ul, ur, cv::USAC_MAGSAC, 1.0, 0.999, inlier);
  if (F.empty()) return {};
  std::vector<cv::Point2f> gl, gr;
  for (std::size_t i = 0; i < inlier.size(); ++i) {
    if (inlier[i] == 0) continue;
    gl.push_back(pl[i]);
    gr.push_back(pr[i]);
  }
  return vertical_disparity(rectifier, gl, gr);
}

}  // namespace wallar::dsp
