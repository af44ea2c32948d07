// SPDX-License-Identifier: Apache-2.0
/// @file test_imu_cam_rotation.cpp
/// @brief IMU-to-camera rotation from gyro vs camera relative rotations, on synthetic motion
/// with a known R_cam_imu (EuRoC's own cam0 rotation).
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "test_support.hpp"
#include "wallar/core/time.hpp"
#include "wallar/dsp/imu/imu_cam_rotation.hpp"
#include "wallar/dsp/imu/visual_rotation.hpp"
#include "wallar/firmware/imu_cam_calibration.hpp"

namespace wallar::test {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

Eigen::Vector3d rotvec_of(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

// EuRoC V1_01's T_BS of cam0 (body = IMU), rotation part, transposed: R_cam_imu.
Eigen::Matrix3d euroc_R_cam_imu() {
  Eigen::Matrix3d R_imu_cam;
  R_imu_cam << 0.0148655429818, -0.999880929698, 0.00414029679422, 0.999557249008, 0.0149672133247,
      0.025715529948, -0.0257744366974, 0.00375618835797, 0.999660727178;
  return Eigen::Quaterniond(R_imu_cam).normalized().toRotationMatrix().transpose();
}

struct Motion {
  std::vector<ImuSample> imu;                //!< 200 Hz, biased gyro
  std::vector<TimeNs> frame_t_ns;            //!< 20 Hz
  std::vector<Eigen::Matrix3d> R_world_imu;  //!< truth at each frame
};

// A body turning about all three axes (rate changing direction), gyro at 200 Hz with bias.
Motion make_motion(double seconds, bool one_axis, const Eigen::Vector3d& bias) {
  Motion m;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  const int n = static_cast<int>(seconds * 200.0);
  const auto rate = [one_axis](double t) {
    return one_axis ? Eigen::Vector3d(0.0, 0.0, 0.8 * std::sin(0.9 * t))
                    : Eigen::Vector3d(0.6 * std::sin(1.1 * t), 0.5 * std::cos(0.7 * t),
                                      0.7 * std::sin(0.5 * t + 0.3));
  };
  for (int i = 0; i <= n; ++i) {
    const double t = i / 200.0;
    ImuSample s;
    s.t_ns = i * 5 * kNsPerMs;
    s.gyro_rad_s = rate(t) + bias;
    m.imu.push_back(s);
    if (i % 10 == 0) {
      m.frame_t_ns.push_back(s.t_ns);
      m.R_world_imu.push_back(q.toRotationMatrix());
    }
    // Truth: the continuous rate, in 100 midpoint steps over the 5 ms to the next sample.
    for (int j = 0; j < 100; ++j) {
      const Eigen::Vector3d w = rate(t + (j + 0.5) * 0.005 / 100.0);
      const double angle = w.norm() * 0.005 / 100.0;
      if (angle > 0.0) q = (q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, w.normalized())));
    }
  }
  return m;
}

TEST(ImuCamRotation, GyroIntegrationMatchesTheTrueRelativeRotation) {
  const Eigen::Vector3d bias(0.01, -0.02, 0.03);
  const Motion m = make_motion(5.0, false, bias);
  const auto rv = dsp::integrate_gyro_rotvec(m.imu, m.frame_t_ns[10], m.frame_t_ns[12], bias);
  ASSERT_TRUE(rv);
  const Eigen::Matrix3d truth = m.R_world_imu[10].transpose() * m.R_world_imu[12];
  // Linear interpolation between samples: within 1e-6 rad of the continuous rotation over
  // 100 ms (holding each rate to the next sample was ~1.6e-4 off, a time shift of its own).
  EXPECT_LT((*rv - rotvec_of(truth)).norm(), 1e-6);
  EXPECT_GT(rv->norm(), 0.02);  // it did turn
  EXPECT_FALSE(dsp::integrate_gyro_rotvec(m.imu, -kNsPerMs, m.frame_t_ns[1], bias));
  EXPECT_FALSE(dsp::integrate_gyro_rotvec(m.imu, m.frame_t_ns[2], m.frame_t_ns[2], bias));
}

TEST(ImuCamRotation, RecoversTheEurocCameraRotationFromNoisyRelativeRotations) {
  const Eigen::Vector3d bias(0.002, 0.02, 0.077);
  const Motion m = make_motion(30.0, false, bias);
  const Eigen::Matrix3d R_cam_imu = euroc_R_cam_imu();
  std::vector<Eigen::Vector3d> imu_rv, cam_rv;
  std::uint64_t state = 99;
  auto noise = [&state] {  // uniform in [-1, 1), deterministic
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) * 0x1.0p-52 - 1.0;
  };
  for (std::size_t k = 0; k + 2 < m.frame_t_ns.size(); k += 2) {  // pairs of frames 100 ms apart
    const auto rv = dsp::integrate_gyro_rotvec(m.imu, m.frame_t_ns[k], m.frame_t_ns[k + 2], bias);
    ASSERT_TRUE(rv);
    const Eigen::Matrix3d R_imu0_imu1 = m.R_world_imu[k].transpose() * m.R_world_imu[k + 2];
    // What the essential matrix of the two images would give, with 0.1-degree errors.
    const Eigen::Vector3d cam = rotvec_of(R_cam_imu * R_imu0_imu1 * R_cam_imu.transpose()) +
                                (0.1 / kRadToDeg) * Eigen::Vector3d(noise(), noise(), noise());
    imu_rv.push_back(*rv);
    cam_rv.push_back(cam);
  }
  const auto r = dsp::solve_R_cam_imu(imu_rv, cam_rv);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->pairs, imu_rv.size());
  const double error_deg =
      Eigen::AngleAxisd(r->R_cam_imu * R_cam_imu.transpose()).angle() * kRadToDeg;
  EXPECT_LT(error_deg, 0.3);
  EXPECT_NEAR(r->R_cam_imu.determinant(), 1.0, 1e-9);
  EXPECT_GT(r->min_axis_spread, 0.3);
  EXPECT_LT(r->residual_rms_rad * kRadToDeg, 0.15);
  // The identity (no calibration) would be far off: the test can tell.
  EXPECT_GT(Eigen::AngleAxisd(R_cam_imu).angle() * kRadToDeg, 80.0);
}

TEST(ImuCamRotation, RotationsAboutOneAxisAreFlaggedAsUndetermined) {
  const Motion m = make_motion(20.0, true, Eigen::Vector3d::Zero());
  const Eigen::Matrix3d R_cam_imu = euroc_R_cam_imu();
  std::vector<Eigen::Vector3d> imu_rv, cam_rv;
  for (std::size_t k = 0; k + 2 < m.frame_t_ns.size(); k += 2) {
    const auto rv = dsp::integrate_gyro_rotvec(m.imu, m.frame_t_ns[k], m.frame_t_ns[k + 2],
                                               Eigen::Vector3d::Zero());
    ASSERT_TRUE(rv);
    imu_rv.push_back(*rv);
    cam_rv.push_back(R_cam_imu * *rv);
  }
  const auto r = dsp::solve_R_cam_imu(imu_rv, cam_rv);
  ASSERT_TRUE(r);
  EXPECT_LT(r->min_axis_spread, 1e-6);
  // The one axis itself is mapped right even so.
  EXPECT_LT((r->R_cam_imu * Eigen::Vector3d::UnitZ() - R_cam_imu * Eigen::Vector3d::UnitZ()).norm(),
            1e-6);
  EXPECT_FALSE(dsp::solve_R_cam_imu(std::span(imu_rv).first(1), std::span(cam_rv).first(1)));
}

// The bundled left camera's intrinsics without distortion, so a homography K R K^-1 is exact.
CameraCalibration pinhole_cam0() {
  CameraCalibration c = recording::read_euroc(bundled_recording()).cams[0].calib;
  c.distortion = {0.0, 0.0, 0.0, 0.0};
  return c;
}

// The image the camera sees after turning by R_cam0_cam1 (bearings b1 = R_cam0_cam1^T b0).
Image rotated_view(const Image& base, const CameraCalibration& c,
                   const Eigen::Matrix3d& R_cam0_cam1) {
  Eigen::Matrix3d K;
  K << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0;
  const Eigen::Matrix3d H = K * R_cam0_cam1.transpose() * K.inverse();
  cv::Matx33d Hcv;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) Hcv(i, j) = H(i, j);
  Image out = Image::allocate(base.width(), base.height(), PixelFormat::kGray8);
  const cv::Mat src(base.height(), base.width(), CV_8UC1, const_cast<std::uint8_t*>(base.data()),
                    static_cast<std::size_t>(base.stride_bytes()));
  cv::Mat dst(out.height(), out.width(), CV_8UC1, out.mutable_data(),
              static_cast<std::size_t>(out.stride_bytes()));
  cv::warpPerspective(src, dst, Hcv, src.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  return out;
}

Image first_left_image() {
  const auto rec = recording::read_euroc(bundled_recording());
  return recording::load_png_gray(rec.cams[0].image_path(rec.cams[0].frames[0]));
}

TEST(ImuCamRotation, CameraRotationBetweenTwoRealImagesTurnedByAKnownRotation) {
  const CameraCalibration cam = pinhole_cam0();
  const Image base = first_left_image();
  const Eigen::Vector3d truth = Eigen::Vector3d(0.02, -0.03, 0.015);  // about 2.2 degrees
  const Image turned = rotated_view(
      base, cam, Eigen::AngleAxisd(truth.norm(), truth.normalized()).toRotationMatrix());
  const auto r = dsp::camera_rotation_between(base, turned, cam);
  ASSERT_TRUE(r);
  EXPECT_GT(r->inliers, 100u);
  EXPECT_LT((r->rotvec_cam0_cam1 - truth).norm() * kRadToDeg, 0.05)
      << r->rotvec_cam0_cam1.transpose();
  // The same image twice: no rotation.
  const auto none = dsp::camera_rotation_between(base, base, cam);
  ASSERT_TRUE(none);
  EXPECT_LT(none->rotvec_cam0_cam1.norm() * kRadToDeg, 0.01);
}

// A recording whose camera turns about three axes in front of the bundled real view, with a
// gyro that turns the same way in EuRoC's IMU frame: calibrate_imu_cam must find EuRoC's
// R_cam_imu. The still bundled recording must be refused with a one-line reason.
TEST(ImuCamRotation, CalibratesARecordingThatTurnsAndRefusesAStillOne) {
  // Half-size images (and intrinsics) keep the PNG writing and reading quick.
  CameraCalibration cam = pinhole_cam0();
  const Image full = first_left_image();
  Image base = Image::allocate(full.width() / 2, full.height() / 2, PixelFormat::kGray8);
  cv::resize(cv::Mat(full.height(), full.width(), CV_8UC1, const_cast<std::uint8_t*>(full.data()),
                     static_cast<std::size_t>(full.stride_bytes())),
             cv::Mat(base.height(), base.width(), CV_8UC1, base.mutable_data(),
                     static_cast<std::size_t>(base.stride_bytes())),
             cv::Size(base.width(), base.height()), 0, 0, cv::INTER_AREA);
  for (double* v : {&cam.fx, &cam.fy, &cam.cx, &cam.cy}) *v *= 0.5;
  cam.width_px = base.width();
  cam.height_px = base.height();
  const Eigen::Matrix3d R_cam_imu = euroc_R_cam_imu();
  auto R_base_cam = [](double t) {  // camera orientation against the base view
    const Eigen::Vector3d th(0.1 * std::sin(3.0 * t), 0.1 * std::sin(2.3 * t + 1.0),
                             0.08 * std::sin(2.7 * t + 2.0));
    return Eigen::AngleAxisd(th.norm(), th.normalized()).toRotationMatrix();
  };
  RigCalibration rig = recording::read_euroc(bundled_recording()).rig();
  for (CameraCalibration& c : rig.cams) {
    const SE3d T_body_cam = c.T_body_cam;
    const std::string name = c.name;
    c = cam;
    c.name = name;
    c.T_body_cam = T_body_cam;
  }
  TempDir tmp;
  {
    recording::EurocWriter writer(tmp.path(), rig);
    const TimeNs t0 = kNsPerS;
    for (int i = 0; i < 2 * 200; ++i) {
      const double t = i / 200.0;
      ImuSample s;
      s.t_ns = t0 + i * 5 * kNsPerMs;
      // The rate held until the next sample, in the camera frame, then in the IMU frame.
      const Eigen::Vector3d w_cam =
          rotvec_of(R_base_cam(t).transpose() * R_base_cam(t + 0.005)) / 0.005;
      s.gyro_rad_s = R_cam_imu.transpose() * w_cam;
      s.accel_m_s2 = Eigen::Vector3d(9.81, 0.0, 0.0);
      writer.write_imu(s);
      if (i % 10 == 0 && i + 10 < 2 * 200) {
        StereoFrame f;
        f.t_ns = f.left.t_ns = f.right.t_ns = s.t_ns;
        f.left.image = rotated_view(base, cam, R_base_cam(t));
        f.right.image = f.left.image;
        writer.write_stereo(f);
      }
    }
    writer.close();
  }
  const auto rec = recording::read_euroc(tmp.path());
  const firmware::ImuCamCalibration c = firmware::calibrate_imu_cam(rec);
  EXPECT_GE(c.solved.pairs, 10u);
  const double error_deg =
      Eigen::AngleAxisd(c.solved.R_cam_imu * R_cam_imu.transpose()).angle() * kRadToDeg;
  EXPECT_LT(error_deg, 0.5);
  EXPECT_LT(c.vs_calibration_deg, 0.5);  // the rig's T_BS holds the same rotation
  EXPECT_GT(c.solved.min_axis_spread, 0.2);
  std::printf(
      "R_cam_imu error %.3f deg from %zu of %zu pairs (residual %.3f deg RMS, spread %.2f)\n",
      error_deg, c.solved.pairs, c.frame_pairs, c.solved.residual_rms_rad * kRadToDeg,
      c.solved.min_axis_spread);

  const auto still = recording::read_euroc(bundled_recording());
  const std::string msg = input_error_of([&] { firmware::calibrate_imu_cam(still); });
  EXPECT_THAT(msg, ::testing::HasSubstr("only 0 frame pairs turn more than 1.0 deg"));
}

}  // namespace
}  // namespace wallar::test
