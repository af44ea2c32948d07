// SPDX-License-Identifier: Apache-2.0
/// @file rectifier.hpp
/// @brief Stereo rectification of a calibrated rig: maps computed once, images remapped into
/// buffers allocated once, and point undistortion for sparse features.
///
/// Rectified cameras share the focal length f, the principal point (cx, cy) and the image rows:
/// a 3-D point seen at row y in one rectified image is at row y in the other, at a disparity of
/// f * baseline / depth. The rectified left camera is the left camera turned by R1 (OpenCV's
/// stereoRectify with CALIB_ZERO_DISPARITY and alpha 0: only valid pixels).
///
/// Threading: construction and rectify() belong to one thread (they share the output
/// buffers); rectify_points() and the accessors are const and may run on any thread.
#pragma once

#include <opencv2/core.hpp>
#include <span>

#include "wallar/core/calibration.hpp"
#include "wallar/core/image.hpp"

namespace wallar::dsp {

/// A header over an 8-bit gray Image (no copy). Throws std::invalid_argument for other formats.
cv::Mat wrap_gray(const Image& image);

class Rectifier {
 public:
  /// Throws std::invalid_argument when the cameras are not radial-tangential pinholes of one
  /// image size, or the rig has no baseline.
  explicit Rectifier(const RigCalibration& rig);

  /// Remaps both images (sizes must match the calibration) into buffers owned by this object,
  /// valid until the next call. Allocates only on the first call.
  void rectify(const Image& left, const Image& right);
  [[nodiscard]] const cv::Mat& left() const { return rect_[0]; }
  [[nodiscard]] const cv::Mat& right() const { return rect_[1]; }

  /// Raw pixel positions of camera `cam` (0 = left) into rectified pixel positions (undistort,
  /// rotate by R1/R2, project with P1/P2). `out` must be as long as `in`.
  void rectify_points(int cam, std::span<const cv::Point2f> in, std::span<cv::Point2f> out) const;

  [[nodiscard]] double f_px() const { return f_px_; }
  [[nodiscard]] double cx() const { return cx_; }
  [[nodiscard]] double cy() const { return cy_; }
  [[nodiscard]] double baseline_m() const { return baseline_m_; }
  [[nodiscard]] cv::Size size() const { return size_; }
  /// Camera `cam` -> its rectified frame.
  [[nodiscard]] const cv::Matx33d& R(int cam) const { return R_[static_cast<std::size_t>(cam)]; }
  [[nodiscard]] const cv::Matx34d& P(int cam) const { return P_[static_cast<std::size_t>(cam)]; }
  /// Camera `cam`'s intrinsics and distortion (as given).
  [[nodiscard]] const cv::Matx33d& K(int cam) const { return K_[static_cast<std::size_t>(cam)]; }
  [[nodiscard]] const cv::Mat& dist(int cam) const { return dist_[static_cast<std::size_t>(cam)]; }
  /// Disparity-to-depth matrix (OpenCV's Q).
  [[nodiscard]] const cv::Matx44d& Q() const { return Q_; }

 private:
  cv::Size size_;
  std::array<cv::Matx33d, 2> K_;
  std::array<cv::Mat, 2> dist_;
  std::array<cv::Matx33d, 2> R_;
  std::array<cv::Matx34d, 2> P_;
  cv::Matx44d Q_;
  std::array<cv::Mat, 2> map_x_, map_y_;
  std::array<cv::Mat, 2> rect_;
  double f_px_ = 0.0, cx_ = 0.0, cy_ = 0.0, baseline_m_ = 0.0;
};

}  // namespace wallar::dsp
