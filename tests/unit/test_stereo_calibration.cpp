// SPDX-License-Identifier: Apache-2.0
/// @file test_stereo_calibration.cpp
/// @brief Stereo calibration on OpenCV's real chessboard pairs and rectification on EuRoC's:
/// the issue's targets, a negative control showing the check can fail, and the rectifier.
#include <cmath>

#include "test_support.hpp"
#include "wallar/drivers/recording/jpeg.hpp"
#include "wallar/dsp/stereo/stereo_calibration.hpp"

namespace wallar::test {
namespace {

const fs::path kPairs = fs::path(WALLAR_TEST_DATA) / "opencv_stereo_calib";
constexpr std::array<int, 13> kNumbers{1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14};

std::string image_name(const char* side, int n) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%s%02d.jpg", side, n);
  return buf;
}

// The 13 pairs, their corners and the calibration: computed once for the suite.
struct Calibrated {
  std::vector<Image> left, right;
  std::vector<std::vector<cv::Point2f>> cl, cr;
  int corners_found = 0;
  dsp::StereoCalibrationResult result;
};

const Calibrated& calibrated() {
  static const Calibrated c = [] {
    Calibrated out;
    for (int n : kNumbers) {
      out.left.push_back(recording::load_image_gray(kPairs / image_name("left", n)));
      out.right.push_back(recording::load_image_gray(kPairs / image_name("right", n)));
      auto a = dsp::find_chessboard(dsp::wrap_gray(out.left.back()), {9, 6});
      auto b = dsp::find_chessboard(dsp::wrap_gray(out.right.back()), {9, 6});
      out.corners_found += (a ? 1 : 0) + (b ? 1 : 0);
      out.cl.push_back(a.value_or(std::vector<cv::Point2f>{}));
      out.cr.push_back(b.value_or(std::vector<cv::Point2f>{}));
    }
    out.result = dsp::calibrate_stereo(out.cl, out.cr, {640, 480}, {{9, 6}, 0.025});
    return out;
  }();
  return c;
}

TEST(StereoCalibration, MeetsTheIssueTargetsOnOpenCvsRealPairs) {
  const Calibrated& c = calibrated();
  EXPECT_EQ(c.corners_found, 26);
  const auto& r = c.result;
  EXPECT_LT(r.rms_px, 0.5);
  EXPECT_EQ(r.views_used.size() + r.views_rejected.size(), 13u);
  EXPECT_GE(r.views_used.size(), 11u);
  for (const CameraCalibration& cam : r.rig.cams) {
    EXPECT_NEAR(cam.fx, 535.9, 0.02 * 535.9) << cam.name;
    EXPECT_NEAR(cam.fy, 535.9, 0.02 * 535.9) << cam.name;
    EXPECT_NEAR(cam.cx, 320.0, 40.0) << cam.name;
    EXPECT_NEAR(cam.cy, 240.0, 40.0) << cam.name;
  }
  // The cameras sit side by side, about 3.3 squares apart, and nearly parallel.
  const SE3d T = r.rig.T_cam0_cam1();
  EXPECT_GT(T.translation().x(), 0.0);  // the right camera is to the left camera's right
  EXPECT_NEAR(r.baseline_m, 0.083, 0.01);
  EXPECT_LT(Eigen::AngleAxisd(T.linear()).angle(), 3.0 * M_PI / 180.0);
  std::printf(
      "rms %.3f px (mono %.3f, %.3f), fx %.2f %.2f, fy %.2f %.2f, baseline %.4f m, "
      "%zu views used\n",
      r.rms_px, r.mono_rms_px[0], r.mono_rms_px[1], r.rig.cams[0].fx, r.rig.cams[1].fx,
      r.rig.cams[0].fy, r.rig.cams[1].fy, r.baseline_m, r.views_used.size());
}

// The rows of rectified pairs, measured with the chessboard corners found independently in
// both images (exact correspondences). Features matched by appearance are no measure on these
// images: the monitor in the scene shows the live feed, the board is a repeated texture, and
// the keyboard another; the EuRoC test below measures with features.
TEST(StereoCalibration, RectifiedPairsAgreeOnRows) {
  const Calibrated& c = calibrated();
  const dsp::Rectifier rect(c.result.rig);
  dsp::VerticalDisparity corners;
  for (std::size_t i = 0; i < c.left.size(); ++i)
    corners.add(dsp::vertical_disparity(rect, c.cl[i], c.cr[i]));
  EXPECT_EQ(corners.count, 13u * 54u);
  EXPECT_LT(corners.mean_px, 0.5);
  std::printf("vertical disparity of the corners: mean %.3f px (median %.3f, max %.3f, n %zu)\n",
              corners.mean_px, corners.median_px, corners.max_px, corners.count);
}

// A rig whose right camera is turned by 1 degree about x (a pitch error).
RigCalibration pitched(RigCalibration rig) {
  rig.cams[1].T_body_cam.linear() =
      rig.cams[1].T_body_cam.linear() *
      Eigen::AngleAxisd(1.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return rig;
}

dsp::VerticalDisparity euroc_features(const RigCalibration& rig, std::size_t step = 8) {
  const recording::EurocRecording rec = recording::read_euroc(bundled_recording());
  const dsp::Rectifier rect(rig);
  dsp::VerticalDisparity features;
  for (std::size_t i = 0; i < rec.cams[0].frames.size(); i += step) {
    const Image l = recording::load_png_gray(rec.cams[0].image_path(rec.cams[0].frames[i]));
    const Image r = recording::load_png_gray(rec.cams[1].image_path(rec.cams[1].frames[i]));
    features.add(dsp::vertical_disparity_of_features(rect, dsp::wrap_gray(l), dsp::wrap_gray(r)));
  }
  return features;
}

TEST(StereoCalibration, EurocPairsRectifyFromTheBundledSensorYaml) {
  const recording::EurocRecording rec = recording::read_euroc(bundled_recording());
  const dsp::Rectifier rect(rec.rig());
  EXPECT_NEAR(rect.baseline_m(), 0.110, 0.002);  // the VI-Sensor's 11 cm
  const dsp::VerticalDisparity features = euroc_features(rec.rig());
  EXPECT_GT(features.count, 1000u);
  EXPECT_LT(features.mean_px, 0.5);
  std::printf("EuRoC: vertical disparity mean %.3f px (median %.3f, max %.3f, n %zu)\n",
              features.mean_px, features.median_px, features.max_px, features.count);
}

TEST(StereoCalibration, TheChecksFailForAWrongCalibration) {
  // Negative controls: 1 degree of pitch between the cameras moves rows by ~ f * 1 deg.
  const Calibrated& c = calibrated();
  const dsp::Rectifier rect(pitched(c.result.rig));
  dsp::VerticalDisparity corners;
  for (std::size_t i = 0; i < c.left.size(); ++i)
    corners.add(dsp::vertical_disparity(rect, c.cl[i], c.cr[i]));
  EXPECT_GT(corners.mean_px, 5.0);
  const dsp::VerticalDisparity features =
      euroc_features(pitched(recording::read_euroc(bundled_recording()).rig()), 20);
  EXPECT_GT(features.mean_px, 5.0);
}

TEST(StereoCalibration, TooFewViewsIsAnError) {
  const Calibrated& c = calibrated();
  const std::vector<std::vector<cv::Point2f>> l(c.cl.begin(), c.cl.begin() + 3);
  const std::vector<std::vector<cv::Point2f>> r(c.cr.begin(), c.cr.begin() + 3);
  EXPECT_THROW((void)dsp::calibrate_stereo(l, r, {640, 480}, {{9, 6}, 0.025}),
               std::invalid_argument);
}

}  // namespace
}  // namespace wallar::test
