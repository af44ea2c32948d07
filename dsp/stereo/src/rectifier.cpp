// SPDX-License-Identifier: Apache-2.0
/// @file rectifier.cpp
/// @brief stereoRectify + initUndistortRectifyMap once; remap and undistortPoints per use.
#include "wallar/dsp/stereo/rectifier.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace wallar::dsp {

cv::Mat wrap_gray(const Image& image) {
  if (image.empty() || image.format() != PixelFormat::kGray8)
    throw std::invalid_argument("expected an 8-bit gray image");
  // OpenCV only reads through this header.
  return cv::Mat(image.height(), image.width(), CV_8UC1, const_cast<std::uint8_t*>(image.data()),
                 static_cast<std::size_t>(image.stride_bytes()));
}

Rectifier::Rectifier(const RigCalibration& rig) {
  for (int i = 0; i < 2; ++i) {
    const CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    if (c.distortion_model != "radial-tangential")
      throw std::invalid_argument("rectification supports radial-tangential cameras only (" +
                                  c.name + " is " + c.distortion_model + ")");
    K_[static_cast<std::size_t>(i)] = {c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0};
    dist_[static_cast<std::size_t>(i)] = cv::Mat(c.distortion, true).reshape(1, 1);
  }
  if (rig.cams[0].width_px != rig.cams[1].width_px ||
      rig.cams[0].height_px != rig.cams[1].height_px || rig.cams[0].width_px <= 0)
    throw std::invalid_argument("rectification needs two cameras of one image size");
  size_ = cv::Size(rig.cams[0].width_px, rig.cams[0].height_px);
  // OpenCV wants the transform from the left to the right camera: T_cam1_cam0.
  const SE3d T_cam1_cam0 = rig.T_cam0_cam1().inverse();
  if (T_cam1_cam0.translation().norm() < 1e-6)
    throw std::invalid_argument("rectification needs a baseline between the cameras");
  cv::Matx33d R;
  cv::Vec3d t;
  for (int i = 0; i < 3; ++i) {
    t[i] = T_cam1_cam0.translation()[i];
    for (int j = 0; j < 3; ++j) R(i, j) = T_cam1_cam0.linear()(i, j);
  }
  cv::Mat R1, R2, P1, P2, Q;
  cv::stereoRectify(K_[0], dist_[0], K_[1], dist_[1], size_, R, t, R1, R2, P1, P2, Q,
                    cv::CALIB_ZERO_DISPARITY, 0.0);
  R_ = {cv::Matx33d(R1), cv::Matx33d(R2)};
  P_ = {cv::Matx34d(P1), cv::Matx34d(P2)};
  Q_ = cv::Matx44d(Q);
  for (std::size_t i = 0; i < 2; ++i)
    cv::initUndistortRectifyMap(K_[i], dist_[i], R_[i], P_[i], size_, CV_16SC2, map_x_[i],
                                map_y_[i]);
  f_px_ = P_[0](0, 0);
  cx_ = P_[0](0, 2);
  cy_ = P_[0](1, 2);
  baseline_m_ = -P_[1](0, 3) / P_[1](0, 0);
}

void Rectifier::rectify(const Image& left, const Image& right) {
  const std::array<const Image*, 2> in{&left, &right};
  for (std::size_t i = 0; i < 2; ++i) {
    if (in[i]->width() != size_.width || in[i]->height() != size_.height)
      throw std::invalid_argument("image size differs from the calibration's");
    cv::remap(wrap_gray(*in[i]), rect_[i], map_x_[i], map_y_[i], cv::INTER_LINEAR);
  }
}

void Rectifier::rectify_points(int cam, std::span<const cv::Point2f> in,
                               std::span<cv::Point2f> out) const {
  if (in.empty()) return;
  if (out.size() < in.size()) throw std::invalid_argument("rectify_points: output too short");
  const auto i = static_cast<std::size_t>(cam);
  const cv::Mat src(static_cast<int>(in.size()), 1, CV_32FC2, const_cast<cv::Point2f*>(in.data()));
  cv::Mat dst(static_cast<int>(in.size()), 1, CV_32FC2, out.data());
  cv::undistortPoints(src, dst, K_[i], dist_[i], R_[i], P_[i]);
}

}  // namespace wallar::dsp
