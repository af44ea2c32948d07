// SPDX-License-Identifier: Apache-2.0
/// @file calibration_files.cpp
/// @brief OpenCV and Kalibr calibration files.
#include "wallar/drivers/recording/calibration_files.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "camera_yaml.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/config/yaml.hpp"
#include "wallar/drivers/recording/csv.hpp"
#include "wallar/drivers/recording/euroc.hpp"

namespace wallar::recording {
namespace fs = std::filesystem;
namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void opencv_matrix(std::ostringstream& s, const std::string& name, const Eigen::MatrixXd& m) {
  s << name << ": !!opencv-matrix\n   rows: " << m.rows() << "\n   cols: " << m.cols()
    << "\n   dt: d\n   data: [ ";
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    for (Eigen::Index c = 0; c < m.cols(); ++c)
      s << num(m(r, c)) << (r + 1 == m.rows() && c + 1 == m.cols() ? " ]\n" : ", ");
}

Eigen::Matrix3d K_of(const CameraCalibration& c) {
  Eigen::Matrix3d K;
  K << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0;
  return K;
}

std::string list(const std::vector<double>& v) {
  std::string out = "[";
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + num(v[i]);
  return out + "]";
}

void kalibr_T(std::ostringstream& s, const char* name, const SE3d& T) {
  s << "  " << name << ":\n";
  const Eigen::Matrix4d m = T.matrix();
  for (int r = 0; r < 4; ++r) s << "  - " << list({m(r, 0), m(r, 1), m(r, 2), m(r, 3)}) << "\n";
}

void check_camera(const config::YamlNode& node, const CameraCalibration& c) {
  if (!(c.fx > 0.0 && c.fy > 0.0 && std::isfinite(c.fx) && std::isfinite(c.fy)))
    node.fail("focal lengths must be positive");
  if (!std::isfinite(c.cx) || !std::isfinite(c.cy)) node.fail("principal point must be finite");
  for (const double d : c.distortion)
    if (!std::isfinite(d)) node.fail("distortion coefficients must be finite");
}

// Checked before converting: a double outside int's range makes the cast undefined.
int pixels(const config::YamlNode& node, double v) {
  if (!(v >= 1.0 && v <= 16384.0) || v != std::floor(v))
    node.fail("must be a pixel count in 1..16384");
  return static_cast<int>(v);
}

CameraCalibration kalibr_camera(const config::YamlNode& cam, int index) {
  CameraCalibration c = detail::read_pinhole_camera(cam, "distortion_coeffs");
  c.name = "cam" + std::to_string(index);
  // wallar's addition (Kalibr has no camera rate and ignores the key): the board's camera mode
  // is checked against it at start.
  if (const config::YamlNode* r = cam.find("rate_hz")) {
    c.rate_hz = r->as_double();
    if (!(c.rate_hz > 0.0 && c.rate_hz <= 1000.0)) r->fail("must be a frame rate in (0, 1000] Hz");
  }
  return c;
}

// `imu_aligned_with_cam0: true` at the top of a calibration file: the IMU's axes are cam0's.
bool imu_aligned_with_cam0(const config::YamlNode& root) {
  const config::YamlNode* n = root.find("imu_aligned_with_cam0");
  return n != nullptr && n->as_bool();
}

RigCalibration parse_kalibr(const config::YamlNode& root) {
  RigCalibration rig;
  const config::YamlNode& c0 = root.at("cam0");
  const config::YamlNode& c1 = root.at("cam1");
  rig.imu_extrinsic_known = c0.has("T_cam_imu") || imu_aligned_with_cam0(root);
  rig.cams[0] = kalibr_camera(c0, 0);
  rig.cams[1] = kalibr_camera(c1, 1);
  // Body: the IMU when cam0 is calibrated against it, else cam0.
  SE3d T_body_cam0 = SE3d::Identity();
  if (const config::YamlNode* t = c0.find("T_cam_imu"))
    T_body_cam0 = detail::read_rigid(*t).inverse();
  rig.cams[0].T_body_cam = T_body_cam0;
  // Kalibr's camera-IMU time offset (seconds): t_imu = t_cam + timeshift_cam_imu.
  if (const config::YamlNode* shift = c0.find("timeshift_cam_imu")) {
    const double s = shift->as_double();
    if (std::abs(s) > 1.0) shift->fail("must be a time offset in seconds within +-1 s");
    rig.imu.timeshift_cam_imu_ns = static_cast<std::int64_t>(std::llround(s * 1e9));
  }
  if (const config::YamlNode* t = c1.find("T_cn_cnm1")) {
    rig.cams[1].T_body_cam = T_body_cam0 * detail::read_rigid(*t).inverse();
  } else if (const config::YamlNode* ti = c1.find("T_cam_imu")) {
    if (!c0.has("T_cam_imu")) ti->fail("needs cam0.T_cam_imu too (or give cam1.T_cn_cnm1)");
    rig.cams[1].T_body_cam = detail::read_rigid(*ti).inverse();
  } else {
    c1.fail("has neither T_cn_cnm1 nor T_cam_imu: the stereo extrinsics are missing");
  }
  // The IMU's noise in Kalibr's imu.yaml names, in the same file (the rig file wallar
  // calibrate writes): what the attitude filter takes.
  if (const config::YamlNode* imu = root.find("imu0")) {
    const auto density = [&](const char* key, double& out) {
      if (const config::YamlNode* n = imu->find(key)) {
        out = n->as_double();
        if (!(out >= 0.0)) n->fail("must be a noise figure >= 0");
      }
    };
    density("gyroscope_noise_density", rig.imu.gyro_noise_density);
    density("gyroscope_random_walk", rig.imu.gyro_random_walk);
    density("accelerometer_noise_density", rig.imu.accel_noise_density);
    density("accelerometer_random_walk", rig.imu.accel_random_walk);
    density("update_rate", rig.imu.rate_hz);
    detail::read_imu_intrinsics(*imu, rig.imu);
  }
  return rig;
}

RigCalibration parse_opencv(const config::YamlNode& root) {
  RigCalibration rig;
  rig.imu_extrinsic_known = imu_aligned_with_cam0(root);
  const int w = pixels(root.at("image_width"), root.at("image_width").as_double());
  const int h = pixels(root.at("image_height"), root.at("image_height").as_double());
  for (int i = 0; i < 2; ++i) {
    const std::string idx = std::to_string(i + 1);
    const config::YamlNode* K = root.find("K" + idx);
    if (K == nullptr) K = root.find("M" + idx);
    if (K == nullptr) root.fail("has no K" + idx + " (or M" + idx + ")");
    const Eigen::MatrixXd k = K->as_matrix(3, 3);
    CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    c.name = "cam" + std::to_string(i);
    c.fx = k(0, 0);
    c.fy = k(1, 1);
    c.cx = k(0, 2);
    c.cy = k(1, 2);
    c.width_px = w;
    c.height_px = h;
    const config::YamlNode& D = root.at("D" + idx);
    std::vector<double> d;
    for (const double v : D.has("data") ? D.at("data").as_doubles() : D.as_doubles())
      d.push_back(v);
    if (d.size() != 4 && d.size() != 5 && d.size() != 8)
      D.fail("must hold 4, 5 or 8 distortion coefficients, got " + std::to_string(d.size()));
    // Beyond k1 k2 p1 p2 k3, OpenCV's rational terms must be zero for radial-tangential.
    for (std::size_t j = 5; j < d.size(); ++j)
      if (d[j] != 0.0) D.fail("has rational-model terms (k4..k6): not supported");
    d.resize(std::min<std::size_t>(d.size(), 5));
    if (d.size() == 5 && d[4] == 0.0) d.resize(4);
    c.distortion = d;
    check_camera(*K, c);
  }
  const Eigen::Matrix3d R3 = root.at("R").as_matrix(3, 3);
  const Eigen::Vector3d T = root.at("T").as_matrix(3, 1);
  if (!R3.allFinite() ||
      !((R3.transpose() * R3 - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-3) ||
      !(R3.determinant() > 0.0))
    root.at("R").fail("is not a rotation");
  if (!T.allFinite()) root.at("T").fail("must be finite");
  SE3d T_cam1_cam0 = SE3d::Identity();
  T_cam1_cam0.linear() = R3;
  T_cam1_cam0.translation() = T;
  rig.cams[0].T_body_cam = SE3d::Identity();
  rig.cams[1].T_body_cam = T_cam1_cam0.inverse();
  return rig;
}

}  // namespace

std::string format_opencv_stereo_yaml(const RigCalibration& rig, const ExtraMatrices& extra) {
  std::ostringstream s;
  s << "%YAML:1.0\n---\n# Stereo calibration written by wallar (OpenCV FileStorage layout).\n"
    << "# x_right = R * x_left + T; distortion k1 k2 p1 p2 [k3].\n"
    << "image_width: " << rig.cams[0].width_px << "\nimage_height: " << rig.cams[0].height_px
    << "\n";
  for (int i = 0; i < 2; ++i) {
    const CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    opencv_matrix(s, "K" + std::to_string(i + 1), K_of(c));
    Eigen::MatrixXd D(1, static_cast<Eigen::Index>(c.distortion.size()));
    for (std::size_t j = 0; j < c.distortion.size(); ++j)
      D(0, static_cast<Eigen::Index>(j)) = c.distortion[j];
    opencv_matrix(s, "D" + std::to_string(i + 1), D);
  }
  const SE3d T_cam1_cam0 = rig.T_cam0_cam1().inverse();
  opencv_matrix(s, "R", T_cam1_cam0.linear());
  opencv_matrix(s, "T", T_cam1_cam0.translation());
  for (const auto& [name, m] : extra) opencv_matrix(s, name, m);
  return s.str();
}

std::string format_kalibr_camchain(const RigCalibration& rig, bool with_imu) {
  std::ostringstream s;
  s << "# Kalibr camchain written by wallar.\n";
  for (int i = 0; i < 2; ++i) {
    const CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    std::vector<double> d = c.distortion;
    if (c.distortion_model == "radial-tangential" && d.size() == 5) {
      if (d[4] != 0.0)
        throw_input_error(c.name, 0, "k3 is not zero: Kalibr's radtan has k1 k2 p1 p2 only");
      d.resize(4);
    }
    s << "cam" << i << ":\n";
    if (with_imu) {
      kalibr_T(s, "T_cam_imu",
               rig.cams[static_cast<std::size_t>(i)].T_body_cam.inverse() * rig.imu.T_body_imu);
      // Kalibr writes the offset per camera; the cameras share one clock here.
      s << "  timeshift_cam_imu: " << format_euroc_double(ns_to_s(rig.imu.timeshift_cam_imu_ns))
        << "\n";
    }
    if (i == 1) kalibr_T(s, "T_cn_cnm1", rig.T_cam0_cam1().inverse());
    s << "  camera_model: pinhole\n  intrinsics: " << list({c.fx, c.fy, c.cx, c.cy})
      << "\n  distortion_model: "
      << (c.distortion_model == "equidistant" ? "equidistant" : "radtan")
      << "\n  distortion_coeffs: " << list(d) << "\n  resolution: [" << c.width_px << ", "
      << c.height_px << "]\n  rostopic: /cam" << i << "/image_raw\n";
    if (c.rate_hz > 0.0) {
      s << "  rate_hz: " << format_euroc_double(c.rate_hz)
        << "  # wallar's: frames per second (the board's camera mode is checked against it)\n";
    }
  }
  const ImuCalibration& imu = rig.imu;
  if (with_imu && (imu.gyro_noise_density > 0.0 || imu.accel_noise_density > 0.0)) {
    s << "imu0:  # Kalibr's imu.yaml names\n"
      << "  gyroscope_noise_density: " << format_euroc_double(imu.gyro_noise_density)
      << "  # [rad/s/sqrt(Hz)]\n"
      << "  gyroscope_random_walk: " << format_euroc_double(imu.gyro_random_walk)
      << "  # [rad/s^2/sqrt(Hz)]\n"
      << "  accelerometer_noise_density: " << format_euroc_double(imu.accel_noise_density)
      << "  # [m/s^2/sqrt(Hz)]\n"
      << "  accelerometer_random_walk: " << format_euroc_double(imu.accel_random_walk)
      << "  # [m/s^3/sqrt(Hz)]\n"
      << "  update_rate: " << format_euroc_double(imu.rate_hz) << "  # [Hz]\n"
      << detail::format_imu_intrinsics(imu, "  ");
  }
  return s.str();
}

RigCalibration parse_rig_calibration(std::string_view text, const std::string& name) {
  const config::YamlDocument doc = config::YamlDocument::parse(text, name);
  const config::YamlNode& root = doc.root();
  if (!root.is_map()) root.fail("must be a map (a Kalibr camchain or an OpenCV stereo YAML)");
  if (root.has("cam0")) return parse_kalibr(root);
  if (root.has("K1") || root.has("M1")) return parse_opencv(root);
  root.fail(
      "is no calibration: expected a Kalibr camchain (cam0, cam1) or an OpenCV stereo YAML "
      "(K1, D1, K2, D2, R, T)");
}

RigCalibration read_rig_calibration(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    const fs::path mav0 = fs::is_directory(path / "mav0", ec) ? path / "mav0" : path;
    RigCalibration rig;
    for (int i = 0; i < 2; ++i) {
      const fs::path yaml = mav0 / ("cam" + std::to_string(i)) / "sensor.yaml";
      if (!fs::is_regular_file(yaml, ec))
        throw_input_error(yaml.string(), 0, "missing (a EuRoC calibration folder needs it)");
      rig.cams[static_cast<std::size_t>(i)] = read_camera_sensor_yaml(yaml);
      rig.cams[static_cast<std::size_t>(i)].name = "cam" + std::to_string(i);
    }
    if (fs::is_regular_file(mav0 / "imu0" / "sensor.yaml", ec))
      rig.imu = read_imu_sensor_yaml(mav0 / "imu0" / "sensor.yaml");
    rig.imu_extrinsic_known = true;  // EuRoC's body frame is the IMU's; T_BS places the cameras
    return rig;
  }
  std::ifstream in(path);
  if (!in) throw_input_error(path.string(), 0, "no such calibration file or folder");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_rig_calibration(text.str(), path.string());
}

}  // namespace wallar::recording
