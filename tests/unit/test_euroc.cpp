// SPDX-License-Identifier: Apache-2.0
/// @file test_euroc.cpp
/// @brief The EuRoC reader on the bundled real recording, the writer's round trip, and one
/// test for every kind of bad input: each error names the file and, where there is one, the line.
#include <gtest/gtest.h>

#include "test_support.hpp"
#include "wallar/drivers/recording/csv.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/stream_stats.hpp"

namespace wallar::test {
namespace {

using recording::EurocRecording;
using recording::read_euroc;
using ::testing::HasSubstr;

TEST(EurocReader, ReadsTheBundledRealRecording) {
  const EurocRecording rec = read_euroc(bundled_recording());
  ASSERT_EQ(rec.cams[0].frames.size(), 40u);
  ASSERT_EQ(rec.cams[1].frames.size(), 40u);
  EXPECT_EQ(rec.cams[0].frames.front().t_ns, 1403715273262142976);
  EXPECT_EQ(rec.cams[0].frames.back().t_ns, 1403715275212143104);
  EXPECT_EQ(rec.imu.size(), 491u);
  EXPECT_EQ(rec.ground_truth.size(), 50u);
  // First IMU row of the file, parsed exactly.
  EXPECT_DOUBLE_EQ(rec.imu.front().gyro_rad_s.x(), -0.0020943951023931952);
  EXPECT_DOUBLE_EQ(rec.imu.front().accel_m_s2.z(), -3.6938381666666662);
  // cam0 sensor.yaml.
  const CameraCalibration& c0 = rec.cams[0].calib;
  EXPECT_EQ(c0.width_px, 752);
  EXPECT_EQ(c0.height_px, 480);
  EXPECT_DOUBLE_EQ(c0.fx, 458.654);
  EXPECT_DOUBLE_EQ(c0.cy, 248.375);
  ASSERT_EQ(c0.distortion.size(), 4u);
  EXPECT_DOUBLE_EQ(c0.distortion[0], -0.28340811);
  EXPECT_NEAR(c0.T_body_cam.translation().x(), -0.0216401454975, 1e-15);
  // The stereo baseline of the VI-Sensor is about 11 cm along the camera x axis.
  EXPECT_NEAR(rec.rig().T_cam0_cam1().translation().norm(), 0.110, 0.002);
  EXPECT_DOUBLE_EQ(rec.imu_calib.rate_hz, 200.0);
  EXPECT_DOUBLE_EQ(rec.imu_calib.gyro_noise_density, 1.6968e-04);
  // Ground truth quaternion (w, x, y, z) of the first row.
  const Eigen::Quaterniond q(rec.ground_truth.front().T_world_body.linear());
  EXPECT_NEAR(std::abs(q.w()), 0.069433, 1e-5);
}

TEST(EurocReader, StreamStatsOfTheBundledRecording) {
  const auto s = recording::recording_stats(read_euroc(bundled_recording()));
  EXPECT_EQ(s.cams[0].count, 40u);
  EXPECT_NEAR(s.cams[0].mean_rate_hz, 20.0, 0.01);
  EXPECT_EQ(s.cams[0].gaps, 0u);
  EXPECT_NEAR(s.imu.mean_rate_hz, 200.0, 0.1);
  EXPECT_EQ(s.imu.gaps, 0u);
  EXPECT_EQ(s.ground_truth_rows, 50u);
}

TEST(StreamStats, FindsGapsAndCountsMissingSamples) {
  // 10 Hz with samples 3 and 4 missing, and one late sample.
  const std::vector<TimeNs> t = {0, 100, 200, 500, 600, 720};
  std::vector<TimeNs> t_ns;
  for (TimeNs v : t) t_ns.push_back(v * kNsPerMs);
  const auto s = recording::stream_stats("x", t_ns, 10.0);
  EXPECT_EQ(s.gaps, 1u);
  EXPECT_EQ(s.missing_samples, 2u);
  EXPECT_EQ(s.max_period_ns, 300 * kNsPerMs);
  EXPECT_EQ(s.max_gap_at_ns, 500 * kNsPerMs);
  EXPECT_EQ(s.median_period_ns, 100 * kNsPerMs);
}

TEST(EurocWriter, WritesWhatTheReaderReadsBack) {
  TempDir tmp;
  write_small_recording(tmp.path(), 5);
  const EurocRecording rec = read_euroc(tmp.path());
  EXPECT_EQ(rec.cams[0].frames.size(), 5u);
  EXPECT_EQ(rec.imu.size(), 50u);
  EXPECT_EQ(rec.cams[1].calib.width_px, 8);
  EXPECT_DOUBLE_EQ(rec.cams[1].calib.distortion[1], -0.002);
  EXPECT_NEAR(rec.cams[1].calib.T_body_cam.translation().x(), 0.055, 1e-15);
  EXPECT_DOUBLE_EQ(rec.imu_calib.accel_random_walk, 3.0e-3);
  const Image img = recording::load_png_gray(rec.cams[0].image_path(rec.cams[0].frames[2]), 8, 6);
  EXPECT_EQ(img.width(), 8);
  // No temporary files left behind.
  for (const auto& e : fs::recursive_directory_iterator(tmp.path())) {
    EXPECT_EQ(e.path().extension(),
              e.path().extension() == ".part" ? ".none" : e.path().extension());
  }
}

TEST(EurocWriter, TheMagnetometerGoesBesideImu0AndComesBackOnItsSamples) {
  // Nothing recorded is lost: an ICM-20948's field readings (every second sample here) go to
  // mav0/mag0/data.csv and come back on the samples that carried them, exactly.
  TempDir tmp;
  {
    recording::EurocWriter writer(tmp.path(), small_rig());
    for (int k = 0; k < 20; ++k) {
      ImuSample s;
      s.t_ns = 1'000'000'000 + k * 5'000'000;
      s.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.81);
      if (k % 2 == 0) s.mag_uT = Eigen::Vector3d(20.0 + 0.1 * k, -3.25, -43.0 - 1.0 / (k + 3));
      writer.write_imu(s);
    }
    EXPECT_EQ(writer.mag_written(), 10u);
  }
  for (const EurocRecording& rec :
       {recording::read_euroc_imu(tmp.path()), read_euroc(tmp.path())}) {
    ASSERT_EQ(rec.imu.size(), 20u);
    for (int k = 0; k < 20; ++k) {
      const ImuSample& s = rec.imu[static_cast<std::size_t>(k)];
      ASSERT_EQ(s.mag_uT.has_value(), k % 2 == 0) << k;
      if (s.mag_uT) {
        EXPECT_EQ(*s.mag_uT, Eigen::Vector3d(20.0 + 0.1 * k, -3.25, -43.0 - 1.0 / (k + 3))) << k;
      }
    }
  }
  // A reading with no IMU sample near it is named, not dropped.
  const fs::path mag = tmp.path() / "mav0" / "mag0" / "data.csv";
  spit(mag, slurp(mag) + "1900000000,1.0,2.0,3.0\n");
  const std::string error = input_error_of([&] { (void)recording::read_euroc_imu(tmp.path()); });
  EXPECT_THAT(error, HasSubstr("mag0/data.csv:12"));
  EXPECT_THAT(error, HasSubstr("no imu0 sample within 50 ms"));
  // Without a magnetometer there is no mag0 folder at all.
  TempDir plain;
  write_small_recording(plain.path(), 2);
  EXPECT_FALSE(fs::exists(plain.path() / "mav0" / "mag0"));
}

TEST(EurocWriter, FormatsDoublesLikeEuroc) {
  EXPECT_EQ(recording::format_euroc_double(0.0), "0.0");
  EXPECT_EQ(recording::format_euroc_double(9.0), "9.0");
  EXPECT_EQ(recording::format_euroc_double(-0.0020943951023931952), "-0.0020943951023931952");
  EXPECT_EQ(recording::format_euroc_double(9.0874956666666655), "9.0874956666666655");
  EXPECT_EQ(recording::format_euroc_double(1e-20), "9.9999999999999995e-21");
}

// ---------------------------------------------------------------------------------------------
// Bad input: one test per case. Each builds a small valid recording, breaks one thing, and
// checks the error names the file and line.

class EurocBadInput : public ::testing::Test {
 protected:
  void SetUp() override { write_small_recording(tmp_.path(), 4); }
  fs::path mav0() const { return tmp_.path() / "mav0"; }
  std::string error() const {
    return input_error_of([&] { (void)read_euroc(tmp_.path()); });
  }
  void replace_line(const fs::path& file, int line, const std::string& text) {
    std::istringstream in(slurp(file));
    std::string out, l;
    for (int n = 1; std::getline(in, l); ++n) out += (n == line ? text : l) + "\n";
    spit(file, out);
  }
  TempDir tmp_;
};

TEST_F(EurocBadInput, MissingRecordingFolder) {
  const std::string e = input_error_of([&] { (void)read_euroc(tmp_.path() / "nope"); });
  EXPECT_THAT(e, HasSubstr("nope: no such recording folder"));
}

TEST_F(EurocBadInput, MissingCameraFolder) {
  fs::remove_all(mav0() / "cam1");
  EXPECT_THAT(error(), HasSubstr("mav0/cam1: missing folder"));
}

// Vision-only recordings are first-class: no imu0 folder, or a data.csv of its header only
// (without sensor.yaml), read as no samples and an identity T_BS; samples without their
// sensor.yaml stay an error.
TEST_F(EurocBadInput, AnImuFolderIsOptional) {
  const fs::path imu0 = mav0() / "imu0";
  const std::string header =
      slurp(imu0 / "data.csv").substr(0, slurp(imu0 / "data.csv").find('\n') + 1);
  fs::remove(imu0 / "sensor.yaml");
  EXPECT_THAT(error(), HasSubstr("imu0/sensor.yaml"));
  spit(imu0 / "data.csv", header);
  EurocRecording rec = read_euroc(tmp_.path());
  EXPECT_TRUE(rec.imu.empty());
  EXPECT_TRUE(rec.imu_calib.T_body_imu.isApprox(SE3d::Identity()));
  EXPECT_EQ(rec.cams[0].frames.size(), 4u);
  fs::remove_all(imu0);
  rec = read_euroc(tmp_.path());
  EXPECT_TRUE(rec.imu.empty());
  EXPECT_EQ(rec.cams[1].frames.size(), 4u);
}

TEST_F(EurocBadInput, MissingCsvFile) {
  fs::remove(mav0() / "imu0" / "data.csv");
  EXPECT_THAT(error(), HasSubstr("imu0/data.csv: no such file"));
}

TEST_F(EurocBadInput, ShortCsvRow) {
  replace_line(mav0() / "imu0" / "data.csv", 4, "1010000000,0.1,0.2");
  EXPECT_THAT(error(), HasSubstr("imu0/data.csv:4: expected 7 fields, found 3 (short row)"));
}

TEST_F(EurocBadInput, LongCsvRow) {
  replace_line(mav0() / "cam0" / "data.csv", 2, "1000000000,1000000000.png,extra");
  EXPECT_THAT(error(), HasSubstr("cam0/data.csv:2: expected 2 fields, found 3 (long row)"));
}

TEST_F(EurocBadInput, NonNumericField) {
  replace_line(mav0() / "imu0" / "data.csv", 3, "1005000000,0.1,abc,0.3,0,0,9.8");
  EXPECT_THAT(error(),
              HasSubstr("imu0/data.csv:3: w_y (column 3) must be a finite number, got 'abc'"));
}

TEST_F(EurocBadInput, NonNumericTimestamp) {
  replace_line(mav0() / "cam1" / "data.csv", 3, "10500OOOOO,1050000000.png");
  EXPECT_THAT(error(), HasSubstr("cam1/data.csv:3: timestamp (column 1) must be an integer"));
}

TEST_F(EurocBadInput, NonFiniteNumber) {
  replace_line(mav0() / "imu0" / "data.csv", 2, "1000000000,nan,0,0,0,0,9.8");
  EXPECT_THAT(error(), HasSubstr("imu0/data.csv:2: w_x (column 2) must be a finite number"));
}

TEST_F(EurocBadInput, NonMonotonicTimestamps) {
  replace_line(mav0() / "imu0" / "data.csv", 5, "1001000000,0,0,0,0,0,9.8");
  EXPECT_THAT(error(),
              HasSubstr("imu0/data.csv:5: timestamp 1001000000 goes back from 1010000000"));
}

TEST_F(EurocBadInput, DuplicateTimestamps) {
  replace_line(mav0() / "cam0" / "data.csv", 3, "1000000000,1000000000.png");
  EXPECT_THAT(error(), HasSubstr("cam0/data.csv:3: duplicate timestamp 1000000000"));
}

TEST_F(EurocBadInput, MissingImageFile) {
  fs::remove(mav0() / "cam1" / "data" / "1100000000.png");
  EXPECT_THAT(error(), HasSubstr("cam1/data.csv:4: image file data/1100000000.png is missing"));
}

TEST_F(EurocBadInput, LeftFrameWithoutItsRight) {
  // Drop the third right frame: the reader accepts it, the strict pairing check names it.
  replace_line(mav0() / "cam1" / "data.csv", 4, "");
  const EurocRecording rec = read_euroc(tmp_.path());
  const std::string e = input_error_of([&] { recording::check_stereo_pairs(rec, 25 * kNsPerMs); });
  EXPECT_THAT(e, HasSubstr("cam0/data.csv:4: left frame 1100000000 has no right frame within "
                           "25.000 ms"));
}

TEST_F(EurocBadInput, UnreadablePng) {
  spit(mav0() / "cam0" / "data" / "1050000000.png", "this is not a PNG");
  const EurocRecording rec = read_euroc(tmp_.path());
  const std::string e = input_error_of(
      [&] { (void)recording::load_png_gray(rec.cams[0].image_path(rec.cams[0].frames[1]), 8, 6); });
  EXPECT_THAT(e, HasSubstr("cam0/data/1050000000.png: unreadable PNG"));
}

TEST_F(EurocBadInput, TruncatedPng) {
  const fs::path png = mav0() / "cam0" / "data" / "1050000000.png";
  const std::string bytes = slurp(png);
  spit(png, bytes.substr(0, bytes.size() / 2));
  const std::string e = input_error_of([&] { (void)recording::load_png_gray(png, 8, 6); });
  EXPECT_THAT(e, HasSubstr("1050000000.png: "));
}

TEST_F(EurocBadInput, WrongSizePng) {
  const std::string e = input_error_of([&] {
    (void)recording::load_png_gray(mav0() / "cam0" / "data" / "1000000000.png", 752, 480);
  });
  EXPECT_THAT(e, HasSubstr("1000000000.png: image is 8x6, expected 752x480"));
}

TEST_F(EurocBadInput, YamlMissingKey) {
  const fs::path yaml = mav0() / "cam0" / "sensor.yaml";
  std::string text = slurp(yaml);
  text.replace(text.find("intrinsics:"), 11, "intrinsix:");
  spit(yaml, text);
  EXPECT_THAT(error(), HasSubstr("cam0/sensor.yaml:3: missing key 'intrinsics'"));
}

TEST_F(EurocBadInput, YamlWrongMatrixSize) {
  const fs::path yaml = mav0() / "imu0" / "sensor.yaml";
  std::string text = slurp(yaml);
  text.replace(text.find("rows: 4"), 7, "rows: 3");
  spit(yaml, text);
  EXPECT_THAT(error(), HasSubstr("imu0/sensor.yaml:6: 'T_BS' must be a 4x4 matrix, is 3x4"));
}

TEST_F(EurocBadInput, YamlWrongListLength) {
  const fs::path yaml = mav0() / "cam1" / "sensor.yaml";
  std::string text = slurp(yaml);
  text.replace(text.find("resolution: [8, 6]"), 18, "resolution: [8, 6, 1]");
  spit(yaml, text);
  EXPECT_THAT(error(), HasSubstr("cam1/sensor.yaml:14: 'resolution' must have 2 entries, has 3"));
}

TEST_F(EurocBadInput, YamlSyntaxError) {
  spit(mav0() / "cam0" / "sensor.yaml", "%YAML:1.0\nT_BS: [1, 2\nrate_hz: 20\n");
  EXPECT_THAT(error(), HasSubstr("cam0/sensor.yaml:3: YAML syntax error"));
}

TEST_F(EurocBadInput, YamlNotARotation) {
  const fs::path yaml = mav0() / "cam0" / "sensor.yaml";
  std::string text = slurp(yaml);
  text.replace(text.find("data: [1.0"), 10, "data: [2.0");
  spit(yaml, text);
  EXPECT_THAT(error(), HasSubstr("'T_BS' is not a rigid transform"));
}

TEST(CsvParser, SkipsCommentsBlankLinesAndCarriageReturns) {
  const std::string text = "#header\r\n1,a.png\r\n\r\n2 , b.png\n";
  const auto frames = recording::parse_camera_csv(text, "x.csv");
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].t_ns, 2);
  EXPECT_EQ(frames[1].filename, "b.png");
  EXPECT_EQ(frames[1].line, 4);
}

TEST(CsvParser, RejectsPathsInFileNames) {
  EXPECT_THAT(
      input_error_of([] { (void)recording::parse_camera_csv("1,../etc/passwd\n", "c.csv"); }),
      HasSubstr("c.csv:1: filename must be a plain file name"));
}

}  // namespace
}  // namespace wallar::test
