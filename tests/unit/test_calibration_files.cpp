// SPDX-License-Identifier: Apache-2.0
/// @file test_calibration_files.cpp
/// @brief OpenCV stereo YAML and Kalibr camchain: written, read back by us and by OpenCV, and
/// Kalibr's own layout (with the IMU) read; bad files named by line and key.
#include <opencv2/core/persistence.hpp>

#include "test_support.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"

namespace wallar::test {
namespace {

using recording::parse_rig_calibration;

RigCalibration sample_rig() {
  RigCalibration rig;
  for (int i = 0; i < 2; ++i) {
    CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    c.name = "cam" + std::to_string(i);
    c.width_px = 640;
    c.height_px = 480;
    c.fx = 535.25 + i;
    c.fy = 535.19 + i;
    c.cx = 342.77 - 14 * i;
    c.cy = 233.64 + 15 * i;
    c.distortion = {-0.285, 0.0828 + 0.01 * i, 0.00137, -0.000134};
  }
  SE3d T = SE3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(0.01, Eigen::Vector3d(0.3, 1.0, 0.2).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.0833, -0.0009, 0.0003);
  rig.cams[1].T_body_cam = T;
  return rig;
}

void expect_same(const RigCalibration& a, const RigCalibration& b) {
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_DOUBLE_EQ(a.cams[i].fx, b.cams[i].fx);
    EXPECT_DOUBLE_EQ(a.cams[i].cy, b.cams[i].cy);
    EXPECT_EQ(a.cams[i].width_px, b.cams[i].width_px);
    ASSERT_EQ(a.cams[i].distortion.size(), b.cams[i].distortion.size());
    for (std::size_t j = 0; j < a.cams[i].distortion.size(); ++j)
      EXPECT_DOUBLE_EQ(a.cams[i].distortion[j], b.cams[i].distortion[j]);
  }
  EXPECT_TRUE(a.T_cam0_cam1().isApprox(b.T_cam0_cam1(), 1e-12));
}

TEST(CalibrationFiles, OpenCvYamlRoundTripsAndOpenCvReadsIt) {
  const RigCalibration rig = sample_rig();
  Eigen::MatrixXd q = Eigen::MatrixXd::Identity(4, 4);
  q(3, 2) = 12.0;
  const std::string text = recording::format_opencv_stereo_yaml(rig, {{"Q", q}});
  expect_same(rig, parse_rig_calibration(text, "cal.yaml"));

  cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  ASSERT_TRUE(fs.isOpened());
  cv::Mat K1, D2, R, T, Q;
  fs["K1"] >> K1;
  fs["D2"] >> D2;
  fs["R"] >> R;
  fs["T"] >> T;
  fs["Q"] >> Q;
  EXPECT_DOUBLE_EQ(K1.at<double>(0, 0), 535.25);
  EXPECT_DOUBLE_EQ(D2.at<double>(0, 1), 0.0928);
  EXPECT_EQ(static_cast<int>(fs["image_width"]), 640);
  EXPECT_DOUBLE_EQ(Q.at<double>(3, 2), 12.0);
  // OpenCV's R, T map left-camera points into the right camera.
  const SE3d T_cam1_cam0 = rig.T_cam0_cam1().inverse();
  EXPECT_NEAR(T.at<double>(0), T_cam1_cam0.translation().x(), 1e-15);
  EXPECT_NEAR(R.at<double>(1, 2), T_cam1_cam0.linear()(1, 2), 1e-15);
}

TEST(CalibrationFiles, ReadsOpenCvsOwnSampleFile) {
  // intrinsics.yml of the bundled OpenCV sample has M1/D1/M2/D2 but no R, T: named as missing.
  const fs::path p = fs::path(WALLAR_TEST_DATA) / "opencv_stereo_calib" / "intrinsics.yml";
  const std::string e = input_error_of([&] { (void)recording::read_rig_calibration(p); });
  EXPECT_THAT(e, ::testing::HasSubstr("intrinsics.yml"));
  EXPECT_THAT(e, ::testing::HasSubstr("image_width"));
}

TEST(CalibrationFiles, KalibrCamchainRoundTripsAndReadsTheImuLayout) {
  const RigCalibration rig = sample_rig();
  expect_same(rig, parse_rig_calibration(recording::format_kalibr_camchain(rig), "camchain.yaml"));

  // Kalibr's camera-IMU output: T_cam_imu on both cameras, T_cn_cnm1 on cam1.
  const char* kalibr = R"(cam0:
  T_cam_imu:
  - [0.0148655429818, 0.999557249008, -0.0257744366974, 0.065222909535]
  - [-0.999880929698, 0.0149672133247, 0.00375618835797, -0.0207022939216]
  - [0.00414029679422, 0.025715529948, 0.999660727178, -0.0080546094713]
  - [0.0, 0.0, 0.0, 1.0]
  camera_model: pinhole
  distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
  distortion_model: radtan
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
cam1:
  T_cn_cnm1:
  - [0.999997256477797, 0.002312067192432, 0.000376008102720, -0.110073808127187]
  - [-0.002317135723275, 0.999898048506644, 0.014089835846691, 0.000399121547014]
  - [-0.000343393120620, -0.014090668452684, 0.999900662637729, -0.000853702503357]
  - [0.0, 0.0, 0.0, 1.0]
  camera_model: pinhole
  distortion_coeffs: [-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05]
  distortion_model: radtan
  intrinsics: [457.587, 456.134, 379.999, 255.238]
  resolution: [752, 480]
  rostopic: /cam1/image_raw
)";
  const RigCalibration k = parse_rig_calibration(kalibr, "camchain-imucam.yaml");
  EXPECT_EQ(k.cams[1].width_px, 752);
  EXPECT_DOUBLE_EQ(k.cams[1].cx, 379.999);
  EXPECT_NEAR(k.T_cam0_cam1().translation().norm(), 0.110, 0.001);
  // The body is the IMU: cam0 sits where EuRoC's T_BS puts it.
  EXPECT_NEAR(k.cams[0].T_body_cam.translation().x(), -0.0216401454975, 1e-5);
}

TEST(CalibrationFiles, TheCameraRateTravelsInTheCamchain) {
  // The board's camera mode is checked against the calibration's rate at start; a rig file
  // without it skipped that check.
  RigCalibration rig = sample_rig();
  rig.cams[0].rate_hz = rig.cams[1].rate_hz = 30.0;
  const std::string text = recording::format_kalibr_camchain(rig, true);
  const RigCalibration back = parse_rig_calibration(text, "c.yaml");
  EXPECT_DOUBLE_EQ(back.cams[0].rate_hz, 30.0);
  EXPECT_DOUBLE_EQ(back.cams[1].rate_hz, 30.0);
  rig.cams[0].rate_hz = rig.cams[1].rate_hz = 0.0;  // unknown: no key, read back as unknown
  const std::string none = recording::format_kalibr_camchain(rig);
  EXPECT_EQ(none.find("rate_hz"), std::string::npos);
  EXPECT_DOUBLE_EQ(parse_rig_calibration(none, "c.yaml").cams[0].rate_hz, 0.0);
  std::string bad = text;
  bad.replace(bad.find("rate_hz: 30"), 11, "rate_hz: -3");
  EXPECT_NE(input_error_of([&] {
              (void)parse_rig_calibration(bad, "c.yaml");
            }).find("'cam0.rate_hz' must be a frame rate"),
            std::string::npos);
}

TEST(CalibrationFiles, TheCameraImuTimeOffsetTravelsInTheCamchain) {
  // `wallar calibrate imu-cam --out` writes Kalibr's timeshift_cam_imu (seconds) beside
  // T_cam_imu; the board's calibration reads it back (the tracker's gyro prior applies it).
  RigCalibration rig = sample_rig();
  rig.imu.timeshift_cam_imu_ns = -7'250'000;
  const std::string text = recording::format_kalibr_camchain(rig, true);
  EXPECT_NE(text.find("timeshift_cam_imu: -0.00725"), std::string::npos) << text;
  EXPECT_EQ(parse_rig_calibration(text, "c.yaml").imu.timeshift_cam_imu_ns, -7'250'000);
  EXPECT_EQ(parse_rig_calibration(recording::format_kalibr_camchain(rig), "c.yaml")
                .imu.timeshift_cam_imu_ns,
            0);  // a stereo-only file has none
  std::string bad = text;
  const std::size_t at = bad.find("timeshift_cam_imu: ") + 19;
  bad.replace(at, bad.find('\n', at) - at, "2.5");
  const std::string error = input_error_of([&] { (void)parse_rig_calibration(bad, "c.yaml"); });
  EXPECT_NE(error.find("timeshift_cam_imu' must be a time offset in seconds"), std::string::npos)
      << error;
}

TEST(CalibrationFiles, TheAccelerometerBiasAndMagnetometerIronTravelInTheRigAndSensorYaml) {
  // `wallar calibrate accel-mag --out` writes them into imu0/sensor.yaml; `calibrate imu-cam
  // --imu` carries them into the rig file; both read back bit for bit, and files without them
  // stay as they were.
  RigCalibration rig = sample_rig();
  rig.imu.rate_hz = 200.0;
  rig.imu.gyro_noise_density = 2.6e-4;
  rig.imu.accel_noise_density = 2.3e-3;
  EXPECT_EQ(recording::format_kalibr_camchain(rig, true).find("accelerometer_bias"),
            std::string::npos);
  EXPECT_EQ(recording::format_imu_sensor_yaml(rig.imu).find("magnetometer"), std::string::npos);
  rig.imu.accel_bias_m_s2 = Eigen::Vector3d(0.0123, -0.0456, 0.1 / 3.0);
  rig.imu.mag_hard_iron_uT = Eigen::Vector3d(26.5, -21.25, 1.0 / 7.0);
  rig.imu.mag_soft_iron << 0.98, 0.063, 0.017, 0.063, 0.99, 0.038, 0.017, 0.038, 1.0 / 0.97;
  const RigCalibration back =
      parse_rig_calibration(recording::format_kalibr_camchain(rig, true), "rig.yaml");
  const ImuCalibration imu =
      recording::parse_imu_sensor_yaml(recording::format_imu_sensor_yaml(rig.imu), "s.yaml");
  for (const ImuCalibration* c : {&back.imu, &imu}) {
    EXPECT_EQ(c->accel_bias_m_s2, rig.imu.accel_bias_m_s2);
    EXPECT_EQ(c->mag_hard_iron_uT, rig.imu.mag_hard_iron_uT);
    EXPECT_EQ(c->mag_soft_iron, rig.imu.mag_soft_iron);
  }
  // A soft iron that cannot be inverted, and a bias no accelerometer has, are named.
  std::string bad = recording::format_imu_sensor_yaml(rig.imu);
  const std::size_t at = bad.find("magnetometer_soft_iron: ") + 24;
  bad.replace(at, bad.find('\n', at) - at, "[1, 0, 0, 0, 1, 0, 0, 0, 0]");
  std::string error =
      input_error_of([&] { (void)recording::parse_imu_sensor_yaml(bad, "s.yaml"); });
  EXPECT_NE(error.find("magnetometer_soft_iron' must be an invertible 3x3 matrix"),
            std::string::npos)
      << error;
  bad = recording::format_imu_sensor_yaml(rig.imu);
  const std::size_t b = bad.find("accelerometer_bias: ") + 20;
  bad.replace(b, bad.find('\n', b) - b, "[9.81, 0, 0]");
  error = input_error_of([&] { (void)recording::parse_imu_sensor_yaml(bad, "s.yaml"); });
  EXPECT_NE(error.find("accelerometer_bias' is over 5 m/s^2"), std::string::npos) << error;
}

TEST(CalibrationFiles, AStereoOnlyFileSaysThatItDoesNotKnowWhereTheImuIs) {
  // A stereo calibration (cam0 as the body) cannot tell an IMU's frame: the flag says so, and a
  // live board with an IMU refuses it (cli.record_live). Kalibr's T_cam_imu, a EuRoC folder's
  // T_BS or an explicit `imu_aligned_with_cam0: true` say where the IMU is.
  const RigCalibration rig = sample_rig();
  EXPECT_FALSE(
      parse_rig_calibration(recording::format_kalibr_camchain(rig), "c.yaml").imu_extrinsic_known);
  EXPECT_TRUE(parse_rig_calibration(recording::format_kalibr_camchain(rig, true), "c.yaml")
                  .imu_extrinsic_known);
  EXPECT_TRUE(
      parse_rig_calibration(
          "imu_aligned_with_cam0: true\n" + recording::format_kalibr_camchain(rig), "c.yaml")
          .imu_extrinsic_known);
  EXPECT_FALSE(
      parse_rig_calibration(
          "imu_aligned_with_cam0: false\n" + recording::format_kalibr_camchain(rig), "c.yaml")
          .imu_extrinsic_known);
  const std::string opencv = recording::format_opencv_stereo_yaml(rig);
  EXPECT_FALSE(parse_rig_calibration(opencv, "s.yaml").imu_extrinsic_known);
  EXPECT_TRUE(parse_rig_calibration(opencv + "imu_aligned_with_cam0: true\n", "s.yaml")
                  .imu_extrinsic_known);
  EXPECT_TRUE(recording::read_rig_calibration(bundled_recording()).imu_extrinsic_known);
  EXPECT_THAT(input_error_of([&] {
                (void)parse_rig_calibration(
                    "imu_aligned_with_cam0: maybe\n" + recording::format_kalibr_camchain(rig),
                    "c.yaml");
              }),
              ::testing::HasSubstr("c.yaml:1"));
}

TEST(CalibrationFiles, EurocFoldersAndBadFilesAreNamed) {
  const RigCalibration euroc = recording::read_rig_calibration(bundled_recording());
  EXPECT_EQ(euroc.cams[0].width_px, 752);
  EXPECT_NEAR(euroc.T_cam0_cam1().translation().norm(), 0.110, 0.001);

  TempDir dir;
  EXPECT_THAT(
      input_error_of([&] { (void)recording::read_rig_calibration(dir.path() / "none.yaml"); }),
      ::testing::HasSubstr("no such calibration file or folder"));
  EXPECT_THAT(input_error_of([&] { (void)recording::read_rig_calibration(dir.path()); }),
              ::testing::HasSubstr("cam0/sensor.yaml: missing"));
  EXPECT_THAT(input_error_of([&] { (void)parse_rig_calibration("a: 1\n", "x.yaml"); }),
              ::testing::HasSubstr("is no calibration"));
  const std::string no_extrinsics =
      "cam0: {intrinsics: [1, 1, 1, 1], distortion_coeffs: [0, 0, 0, 0], resolution: [4, 4]}\n"
      "cam1: {intrinsics: [1, 1, 1, 1], distortion_coeffs: [0, 0, 0, 0], resolution: [4, 4]}\n";
  EXPECT_THAT(input_error_of([&] { (void)parse_rig_calibration(no_extrinsics, "c.yaml"); }),
              ::testing::HasSubstr("c.yaml:2"));
  std::string bad = recording::format_opencv_stereo_yaml(sample_rig());
  bad.replace(bad.find("R: !!opencv-matrix"), 1, "X");
  EXPECT_THAT(input_error_of([&] { (void)parse_rig_calibration(bad, "s.yaml"); }),
              ::testing::HasSubstr("missing key 'R'"));
}

}  // namespace
}  // namespace wallar::test
