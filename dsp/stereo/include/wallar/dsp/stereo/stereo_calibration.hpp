// SPDX-License-Identifier: Apache-2.0
/// @file stereo_calibration.hpp
/// @brief Stereo calibration from chessboard image pairs, and the check that a calibration
/// rectifies real image pairs: matched features must land on the same rectified row.
///
/// Calibration: chessboard corners (cv::findChessboardCorners, refined to sub-pixel with
/// cv::cornerSubPix), each camera calibrated alone (cv::calibrateCamera), then both together
/// (cv::stereoCalibrate, starting from the single-camera intrinsics and refining them). Views
/// whose reprojection RMS is far above the others (more than `reject_factor` x the median and
/// more than `reject_floor_px`) are dropped and the rig is solved again; which ones is reported.
/// The distortion model is radial-tangential with four coefficients (k1, k2, p1, p2), the model
/// of EuRoC's sensor.yaml and Kalibr's radtan, so every file we write is read by those tools.
///
/// Threading: free functions on their arguments only.
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/dsp/stereo/rectifier.hpp"

namespace wallar::dsp {

struct ChessboardSpec {
  cv::Size inner_corners{9, 6};  //!< corners per row, per column
  double square_m = 0.025;       //!< side of one square
};

/// The chessboard's inner corners in `gray`, sub-pixel refined, in OpenCV's order; nullopt when
/// the whole board is not found.
std::optional<std::vector<cv::Point2f>> find_chessboard(const cv::Mat& gray, cv::Size inner);

struct StereoCalibrationParams {
  double reject_factor = 3.0;    //!< a view is bad above reject_factor x the median view RMS ...
  double reject_floor_px = 1.0;  //!< ... and above this
  std::size_t min_views = 5;
};

struct StereoCalibrationResult {
  /// body = the left camera: T_body_cam0 = identity, T_body_cam1 = T_cam0_cam1.
  RigCalibration rig;
  double rms_px = 0.0;                  //!< stereo reprojection RMS over both cameras
  std::array<double, 2> mono_rms_px{};  //!< each camera calibrated alone
  std::vector<std::size_t> views_used;  //!< indices into the input views
  std::vector<std::size_t> views_rejected;
  std::vector<double> view_rms_px;  //!< per used view, both cameras
  double baseline_m = 0.0;
};

/// Calibrates from corner lists of the same views in both cameras (one entry per view; views
/// are pairs taken at the same time). Throws std::invalid_argument when fewer than min_views
/// views remain.
StereoCalibrationResult calibrate_stereo(std::span<const std::vector<cv::Point2f>> left,
                                         std::span<const std::vector<cv::Point2f>> right,
                                         cv::Size image_size, const ChessboardSpec& board,
                                         const StereoCalibrationParams& params = {});

/// |y_left - y_right| of corresponding points after rectification [px].
struct VerticalDisparity {
  std::size_t count = 0;
  double mean_px = 0.0;
  double median_px = 0.0;
  double max_px = 0.0;
  void add(const VerticalDisparity& other);  //!< pools counts and means (median: count-weighted)
};

/// For known correspondences (e.g. chessboard corners found in both raw images).
VerticalDisparity vertical_disparity(const Rectifier& rectifier,
                                     std::span<const cv::Point2f> left_raw,
                                     std::span<const cv::Point2f> right_raw);

/// For features matched between two raw images: ORB matches (mutual, distinctive by the ratio
/// test), refined to sub-pixel by Lucas-Kanade with a forward-backward check, and gross
/// mismatches removed by a fundamental matrix estimated by RANSAC (MAGSAC) from the matches
/// themselves on undistorted points, not from the calibration, so the check does not grade
/// itself. It needs a static, textured scene: moving things (a monitor showing the live feed,
/// a person) and repeated texture (a chessboard) defeat the data's own epipolar geometry.
VerticalDisparity vertical_disparity_of_features(const Rectifier& rectifier,
                                                 const cv::Mat& left_raw, const cv::Mat& right_raw,
                                                 int max_features = 2000);

}  // namespace wallar::dsp
