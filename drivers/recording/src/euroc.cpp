// SPDX-License-Identifier: Apache-2.0
/// @file euroc.cpp
/// @brief EuRoC/ASL recording reader and writer.
#include "wallar/drivers/recording/euroc.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "camera_yaml.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/config/yaml.hpp"
#include "wallar/drivers/recording/csv.hpp"

namespace wallar::recording {
namespace fs = std::filesystem;
namespace {

constexpr const char* kCamHeader = "#timestamp [ns],filename\n";
constexpr const char* kImuHeader =
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";

// Timestamps must increase strictly: a repeat or a step back is a broken recording.
void check_monotonic(const CsvRow& row, TimeNs previous_ns, TimeNs t_ns, bool first) {
  if (first) return;
  if (t_ns == previous_ns) row.fail("duplicate timestamp " + std::to_string(t_ns));
  if (t_ns < previous_ns) {
    row.fail("timestamp " + std::to_string(t_ns) + " goes back from " +
             std::to_string(previous_ns) + " (non-monotonic)");
  }
}

void write_all(int fd, const std::string& text, const fs::path& path) {
  const char* p = text.data();
  std::size_t left = text.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw_input_error(path.string(), 0, std::string("write failed: ") + std::strerror(errno));
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
}

int open_csv(const fs::path& path, const char* header) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0)
    throw_input_error(path.string(), 0, std::string("cannot create: ") + std::strerror(errno));
  write_all(fd, header, path);
  return fd;
}

std::string format_T_BS(const SE3d& T) {
  std::ostringstream s;
  s.precision(17);
  s << "T_BS:\n  cols: 4\n  rows: 4\n  data: [";
  const Eigen::Matrix4d m = T.matrix();
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      s << format_euroc_double(m(i, j)) << (i == 3 && j == 3 ? "]\n" : ", ");
    }
  }
  return s.str();
}

// `sync`: fsync before closing (the small sensor files; images are many and go unsynced, as
// save_png's do).
void write_text_file(const fs::path& path, const std::string& text, bool sync = true) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0)
    throw_input_error(path.string(), 0, std::string("cannot create: ") + std::strerror(errno));
  write_all(fd, text, path);
  if (sync) ::fsync(fd);
  ::close(fd);
}

}  // namespace

std::vector<FrameEntry> parse_camera_csv(std::string_view text, const std::string& name) {
  std::vector<FrameEntry> frames;
  parse_csv(text, name, 2, [&](const CsvRow& row) {
    const TimeNs t_ns = row.int64_at(0, "timestamp");
    check_monotonic(row, frames.empty() ? 0 : frames.back().t_ns, t_ns, frames.empty());
    const std::string_view file = row.fields[1];
    if (file.empty() || file.find('/') != std::string_view::npos || file == "." || file == "..") {
      row.fail("filename must be a plain file name, got '" + std::string(file.substr(0, 64)) + "'");
    }
    frames.push_back(FrameEntry{t_ns, std::string(file), row.line});
  });
  return frames;
}

std::vector<ImuSample> parse_imu_csv(std::string_view text, const std::string& name) {
  std::vector<ImuSample> samples;
  parse_csv(text, name, 7, [&](const CsvRow& row) {
    ImuSample s;
    s.t_ns = row.int64_at(0, "timestamp");
    check_monotonic(row, samples.empty() ? 0 : samples.back().t_ns, s.t_ns, samples.empty());
    s.gyro_rad_s = {row.double_at(1, "w_x"), row.double_at(2, "w_y"), row.double_at(3, "w_z")};
    s.accel_m_s2 = {row.double_at(4, "a_x"), row.double_at(5, "a_y"), row.double_at(6, "a_z")};
    samples.push_back(s);
  });
  return samples;
}

namespace {

constexpr const char* kMagHeader = "#timestamp [ns],m_RS_S_x [uT],m_RS_S_y [uT],m_RS_S_z [uT]\n";
// A magnetometer row belongs to the first IMU sample at or after it, no later than this.
constexpr DurationNs kMagToImuMaxNs = 50 * kNsPerMs;

// mav0/mag0/data.csv (wallar's, beside EuRoC's imu0: the magnetometer an ICM-20948 or BNO055
// carries), attached to the IMU samples: the writer stamps each row with its IMU sample's time.
void read_magnetometer(const fs::path& mav0, std::vector<ImuSample>& imu) {
  std::error_code ec;
  const fs::path csv = mav0 / "mag0" / "data.csv";
  if (!fs::exists(csv, ec)) return;
  const std::string name = csv.string();
  TimeNs last_t_ns = 0;
  bool first = true;
  parse_csv(read_text_file(csv), name, 4, [&](const CsvRow& row) {
    const TimeNs t_ns = row.int64_at(0, "timestamp");
    check_monotonic(row, last_t_ns, t_ns, first);
    first = false;
    last_t_ns = t_ns;
    const Eigen::Vector3d m(row.double_at(1, "m_x"), row.double_at(2, "m_y"),
                            row.double_at(3, "m_z"));
    const auto it = std::lower_bound(imu.begin(), imu.end(), t_ns,
                                     [](const ImuSample& s, TimeNs t) { return s.t_ns < t; });
    if (it == imu.end() || it->t_ns - t_ns > kMagToImuMaxNs) {
      row.fail("has no imu0 sample within 50 ms at or after it");
    }
    it->mag_uT = m;  // a faster magnetometer than IMU: the newest reading per sample
  });
}

}  // namespace

std::vector<GroundTruthState> parse_ground_truth_csv(std::string_view text,
                                                     const std::string& name) {
  std::vector<GroundTruthState> states;
  parse_csv(text, name, 17, [&](const CsvRow& row) {
    GroundTruthState g;
    g.t_ns = row.int64_at(0, "timestamp");
    check_monotonic(row, states.empty() ? 0 : states.back().t_ns, g.t_ns, states.empty());
    const Eigen::Vector3d p(row.double_at(1, "p_x"), row.double_at(2, "p_y"),
                            row.double_at(3, "p_z"));
    const Eigen::Quaterniond q(row.double_at(4, "q_w"), row.double_at(5, "q_x"),
                               row.double_at(6, "q_y"), row.double_at(7, "q_z"));
    if (std::abs(q.norm() - 1.0) > 1e-2) row.fail("quaternion is not unit length");
    g.T_world_body = make_se3(q, p);
    g.vel_world_m_s = {row.double_at(8, "v_x"), row.double_at(9, "v_y"), row.double_at(10, "v_z")};
    g.gyro_bias_rad_s = {row.double_at(11, "bw_x"), row.double_at(12, "bw_y"),
                         row.double_at(13, "bw_z")};
    g.accel_bias_m_s2 = {row.double_at(14, "ba_x"), row.double_at(15, "ba_y"),
                         row.double_at(16, "ba_z")};
    states.push_back(g);
  });
  return states;
}

std::string_view ground_truth_csv_header() {
  return "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
         "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], "
         "b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], "
         "b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n";
}

std::string format_ground_truth_row(const GroundTruthState& g) {
  Eigen::Quaterniond q(g.T_world_body.linear());
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d& p = g.T_world_body.translation();
  std::string row = std::to_string(g.t_ns);
  const auto add = [&row](double v) {
    row += ',';
    row += format_euroc_double(v);
  };
  for (int i = 0; i < 3; ++i) add(p[i]);
  for (const double v : {q.w(), q.x(), q.y(), q.z()}) add(v);
  for (const Eigen::Vector3d* v : {&g.vel_world_m_s, &g.gyro_bias_rad_s, &g.accel_bias_m_s2}) {
    for (int i = 0; i < 3; ++i) add((*v)[i]);
  }
  row += '\n';
  return row;
}

namespace detail {

SE3d read_rigid(const config::YamlNode& node) {
  const Eigen::Matrix4d m = node.as_matrix(4, 4);
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  // A rotation must be orthonormal with det +1; a typo in a calibration file is caught here.
  // Written so that NaN fails too: huge finite entries (1e200) overflow R^T R to inf - inf.
  const double orthonormality_error =
      (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!m.allFinite() || !(orthonormality_error <= 1e-3) || !(R.determinant() > 0.0)) {
    node.fail("is not a rigid transform (rotation part not orthonormal)");
  }
  SE3d T = SE3d::Identity();
  T.linear() = R;
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

CameraCalibration read_pinhole_camera(const config::YamlNode& node,
                                      std::string_view distortion_key) {
  CameraCalibration c;
  const config::YamlNode& res_node = node.at("resolution");
  const std::vector<double> res = res_node.as_doubles(2);
  // Check before converting: a double outside int's range (1e10) makes the cast undefined.
  for (const double px : res) {
    if (!(px >= 1.0 && px <= 16384.0) || px != std::floor(px)) {
      res_node.fail("must be two positive pixel counts");
    }
  }
  c.width_px = static_cast<int>(res[0]);
  c.height_px = static_cast<int>(res[1]);
  const std::string model = node.get_string("camera_model", "pinhole");
  if (model != "pinhole") node.at("camera_model").fail("must be 'pinhole', got '" + model + "'");
  const config::YamlNode& k_node = node.at("intrinsics");
  const std::vector<double> k = k_node.as_doubles(4);
  c.fx = k[0];
  c.fy = k[1];
  c.cx = k[2];
  c.cy = k[3];
  if (!(c.fx > 0.0 && c.fy > 0.0 && std::isfinite(c.fx) && std::isfinite(c.fy)))
    k_node.fail("focal lengths must be positive");
  if (!std::isfinite(c.cx) || !std::isfinite(c.cy)) k_node.fail("principal point must be finite");
  c.distortion_model = node.get_string("distortion_model", "radial-tangential");
  if (c.distortion_model == "radial-tangential" || c.distortion_model == "radtan") {
    c.distortion_model = "radial-tangential";
  } else if (c.distortion_model != "equidistant") {
    node.at("distortion_model").fail("must be radial-tangential (radtan) or equidistant");
  }
  const config::YamlNode& d_node = node.at(distortion_key);
  c.distortion = d_node.as_doubles(4);
  for (const double d : c.distortion)
    if (!std::isfinite(d)) d_node.fail("distortion coefficients must be finite");
  return c;
}

void read_imu_intrinsics(const config::YamlNode& map, ImuCalibration& imu) {
  const auto finite = [](const config::YamlNode& n, std::size_t count) {
    const std::vector<double> v = n.as_doubles(count);
    for (const double x : v) {
      if (!std::isfinite(x)) n.fail("must be finite numbers");
    }
    return v;
  };
  if (const config::YamlNode* n = map.find("accelerometer_bias")) {
    const std::vector<double> v = finite(*n, 3);
    imu.accel_bias_m_s2 = Eigen::Vector3d(v[0], v[1], v[2]);
    if (imu.accel_bias_m_s2.norm() > 5.0) n->fail("is over 5 m/s^2: not a bias");
  }
  if (const config::YamlNode* n = map.find("magnetometer_hard_iron")) {
    const std::vector<double> v = finite(*n, 3);
    imu.mag_hard_iron_uT = Eigen::Vector3d(v[0], v[1], v[2]);
  }
  if (const config::YamlNode* n = map.find("magnetometer_soft_iron")) {
    const std::vector<double> v = finite(*n, 9);
    for (int i = 0; i < 9; ++i) imu.mag_soft_iron(i / 3, i % 3) = v[static_cast<std::size_t>(i)];
    const double det = imu.mag_soft_iron.determinant();
    if (!(std::abs(det) > 1e-6)) n->fail("must be an invertible 3x3 matrix (row-major)");
  }
}

std::string format_imu_intrinsics(const ImuCalibration& imu, std::string_view indent) {
  const auto list = [](const double* v, int n) {
    std::string s = "[";
    for (int i = 0; i < n; ++i) {
      if (i != 0) s += ", ";
      s += format_euroc_double(v[i]);
    }
    return s + "]";
  };
  std::string s;
  const std::string in(indent);
  if (imu.has_accel_bias()) {
    s += in + "accelerometer_bias: " + list(imu.accel_bias_m_s2.data(), 3) + "  # [m/s^2]\n";
  }
  if (imu.has_mag_correction()) {
    const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> S = imu.mag_soft_iron;
    s += in + "magnetometer_hard_iron: " + list(imu.mag_hard_iron_uT.data(), 3) + "  # [uT]\n";
    s += in + "magnetometer_soft_iron: " + list(S.data(), 9) +
         "  # row-major: field = S (m - hard_iron)\n";
  }
  return s;
}

}  // namespace detail

CameraCalibration parse_camera_sensor_yaml(std::string_view text, const std::string& name) {
  const config::YamlDocument doc = config::YamlDocument::parse(text, name);
  const config::YamlNode& root = doc.root();
  if (!root.is_map()) root.fail("must be a map of sensor settings");
  const SE3d T_body_cam = detail::read_rigid(root.at("T_BS"));
  CameraCalibration c = detail::read_pinhole_camera(root, "distortion_coefficients");
  c.T_body_cam = T_body_cam;
  c.rate_hz = root.at("rate_hz").as_double();
  if (c.rate_hz <= 0.0) root.at("rate_hz").fail("must be positive");
  return c;
}

CameraCalibration read_camera_sensor_yaml(const fs::path& path) {
  return parse_camera_sensor_yaml(read_text_file(path), path.string());
}

ImuCalibration parse_imu_sensor_yaml(std::string_view text, const std::string& name) {
  const config::YamlDocument doc = config::YamlDocument::parse(text, name);
  const config::YamlNode& root = doc.root();
  if (!root.is_map()) root.fail("must be a map of sensor settings");
  ImuCalibration c;
  c.T_body_imu = detail::read_rigid(root.at("T_BS"));
  c.rate_hz = root.at("rate_hz").as_double();
  if (c.rate_hz <= 0.0) root.at("rate_hz").fail("must be positive");
  c.gyro_noise_density = root.at("gyroscope_noise_density").as_double();
  c.gyro_random_walk = root.at("gyroscope_random_walk").as_double();
  c.accel_noise_density = root.at("accelerometer_noise_density").as_double();
  c.accel_random_walk = root.at("accelerometer_random_walk").as_double();
  // Optional (Kalibr's name, seconds): t_imu = t_cam + timeshift_cam_imu.
  if (const config::YamlNode* shift = root.find("timeshift_cam_imu")) {
    const double s = shift->as_double();
    if (!std::isfinite(s) || std::abs(s) > 1.0) shift->fail("must be within +-1 s");
    c.timeshift_cam_imu_ns = static_cast<std::int64_t>(std::llround(s * 1e9));
  }
  detail::read_imu_intrinsics(root, c);
  return c;
}

ImuCalibration read_imu_sensor_yaml(const fs::path& path) {
  return parse_imu_sensor_yaml(read_text_file(path), path.string());
}

std::vector<std::uint8_t> load_frame_encoded(const EurocRecording& rec, int cam,
                                             const FrameEntry& f) {
  if (rec.store) return rec.store->encoded(cam, f);
  const fs::path path = rec.cams[static_cast<std::size_t>(cam)].image_path(f);
  const std::string text = read_text_file(path);
  return {text.begin(), text.end()};
}

Image load_frame_gray(const EurocRecording& rec, int cam, const FrameEntry& f) {
  const CameraStream& c = rec.cams[static_cast<std::size_t>(cam)];
  if (!rec.store) return load_png_gray(c.image_path(f), c.calib.width_px, c.calib.height_px);
  return decode_png_gray(rec.store->encoded(cam, f), rec.store->describe(cam, f), c.calib.width_px,
                         c.calib.height_px);
}

const GroundTruthState* nearest_ground_truth(const EurocRecording& rec, TimeNs t_ns) {
  if (rec.ground_truth.empty()) return nullptr;
  return &*std::min_element(rec.ground_truth.begin(), rec.ground_truth.end(),
                            [&](const auto& a, const auto& b) {
                              return std::llabs(a.t_ns - t_ns) < std::llabs(b.t_ns - t_ns);
                            });
}

std::optional<GroundTruthState> ground_truth_at(const std::vector<GroundTruthState>& gt,
                                                TimeNs t_ns, DurationNs max_gap_ns) {
  if (gt.empty() || t_ns < gt.front().t_ns || t_ns > gt.back().t_ns) return std::nullopt;
  const auto after = std::lower_bound(
      gt.begin(), gt.end(), t_ns, [](const GroundTruthState& g, TimeNs t) { return g.t_ns < t; });
  if (after->t_ns == t_ns) return *after;
  const GroundTruthState& a = *(after - 1);
  const GroundTruthState& b = *after;
  if (t_ns - a.t_ns > max_gap_ns && b.t_ns - t_ns > max_gap_ns) return std::nullopt;
  const double f = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  GroundTruthState g;
  g.t_ns = t_ns;
  const Eigen::Quaterniond qa(a.T_world_body.linear());
  const Eigen::Quaterniond qb(b.T_world_body.linear());
  g.T_world_body = make_se3(
      qa.slerp(f, qb), (1.0 - f) * a.T_world_body.translation() + f * b.T_world_body.translation());
  g.vel_world_m_s = (1.0 - f) * a.vel_world_m_s + f * b.vel_world_m_s;
  g.gyro_bias_rad_s = (1.0 - f) * a.gyro_bias_rad_s + f * b.gyro_bias_rad_s;
  g.accel_bias_m_s2 = (1.0 - f) * a.accel_bias_m_s2 + f * b.accel_bias_m_s2;
  return g;
}

EurocRecording read_euroc_imu(const fs::path& root) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw_input_error(root.string(), 0, "no such recording folder");
  EurocRecording rec;
  rec.mav0 = fs::is_directory(root / "mav0", ec) ? root / "mav0" : root;
  if (!fs::is_directory(rec.mav0 / "imu0", ec)) {
    throw_input_error((rec.mav0 / "imu0").string(), 0,
                      "missing folder (an inertial recording needs mav0/imu0)");
  }
  const fs::path imu_csv = rec.mav0 / "imu0" / "data.csv";
  rec.imu = parse_imu_csv(read_text_file(imu_csv), imu_csv.string());
  read_magnetometer(rec.mav0, rec.imu);
  if (fs::exists(rec.mav0 / "imu0" / "sensor.yaml", ec)) {
    rec.imu_calib = read_imu_sensor_yaml(rec.mav0 / "imu0" / "sensor.yaml");
  }
  for (int i = 0; i < 2; ++i) {
    CameraStream& cam = rec.cams[static_cast<std::size_t>(i)];
    cam.dir = rec.mav0 / ("cam" + std::to_string(i));
    if (!fs::exists(cam.dir / "sensor.yaml", ec)) continue;
    cam.calib = read_camera_sensor_yaml(cam.dir / "sensor.yaml");
    cam.calib.name = "cam" + std::to_string(i);
  }
  const fs::path gt_csv = rec.mav0 / "state_groundtruth_estimate0" / "data.csv";
  if (fs::exists(gt_csv, ec)) {
    rec.ground_truth = parse_ground_truth_csv(read_text_file(gt_csv), gt_csv.string());
  }
  return rec;
}

EurocRecording read_euroc(const fs::path& root, const ReadOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw_input_error(root.string(), 0, "no such recording folder");
  EurocRecording rec;
  rec.mav0 = fs::is_directory(root / "mav0", ec) ? root / "mav0" : root;
  for (const char* sub : {"cam0", "cam1"}) {
    if (!fs::is_directory(rec.mav0 / sub, ec)) {
      throw_input_error((rec.mav0 / sub).string(), 0,
                        "missing folder (an EuRoC recording needs mav0/cam0 and cam1)");
    }
  }
  for (int i = 0; i < 2; ++i) {
    CameraStream& cam = rec.cams[static_cast<std::size_t>(i)];
    cam.dir = rec.mav0 / ("cam" + std::to_string(i));
    cam.calib = read_camera_sensor_yaml(cam.dir / "sensor.yaml");
    cam.calib.name = "cam" + std::to_string(i);
    const fs::path csv = cam.dir / "data.csv";
    cam.frames = parse_camera_csv(read_text_file(csv), csv.string());
    if (options.check_image_files) {
      for (const FrameEntry& f : cam.frames) {
        if (!fs::is_regular_file(cam.image_path(f), ec)) {
          throw_input_error(csv.string(), f.line, "image file data/" + f.filename + " is missing");
        }
      }
    }
  }
  // The IMU is optional: no imu0 folder, or a data.csv of its header only, is a vision-only
  // recording (no samples, identity T_BS); samples need their sensor.yaml.
  if (fs::is_directory(rec.mav0 / "imu0", ec)) {
    const fs::path imu_csv = rec.mav0 / "imu0" / "data.csv";
    rec.imu = parse_imu_csv(read_text_file(imu_csv), imu_csv.string());
    read_magnetometer(rec.mav0, rec.imu);
    const fs::path imu_yaml = rec.mav0 / "imu0" / "sensor.yaml";
    if (!rec.imu.empty() || fs::exists(imu_yaml, ec))
      rec.imu_calib = read_imu_sensor_yaml(imu_yaml);
  }
  const fs::path gt_csv = rec.mav0 / "state_groundtruth_estimate0" / "data.csv";
  if (fs::exists(gt_csv, ec)) {
    rec.ground_truth = parse_ground_truth_csv(read_text_file(gt_csv), gt_csv.string());
  }
  return rec;
}

void check_stereo_pairs(const EurocRecording& rec, DurationNs tolerance_ns) {
  static constexpr const char* kSide[2] = {"left", "right"};
  for (std::size_t c = 0; c < 2; ++c) {
    const auto& mine = rec.cams[c].frames;
    const auto& other = rec.cams[1 - c].frames;
    std::size_t j = 0;
    for (const FrameEntry& f : mine) {
      // Both lists increase: advance to the first partner candidate not too early.
      while (j < other.size() && other[j].t_ns < f.t_ns - tolerance_ns) ++j;
      if (j < other.size() && std::llabs(other[j].t_ns - f.t_ns) <= tolerance_ns) continue;
      char msg[160];
      std::snprintf(msg, sizeof msg, "%s frame %lld has no %s frame within %.3f ms", kSide[c],
                    static_cast<long long>(f.t_ns), kSide[1 - c],
                    static_cast<double>(tolerance_ns) * 1e-6);
      throw_input_error((rec.cams[c].dir / "data.csv").string(), f.line, msg);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Writer

std::string format_camera_sensor_yaml(const CameraCalibration& c) {
  std::ostringstream s;
  s << "%YAML:1.0\n# General sensor definitions.\nsensor_type: camera\ncomment: " << c.name
    << " (written by wallar)\n\n# Sensor extrinsics wrt. the body-frame.\n"
    << format_T_BS(c.T_body_cam)
    << "\n# Camera specific definitions.\nrate_hz: " << format_euroc_double(c.rate_hz)
    << "\nresolution: [" << c.width_px << ", " << c.height_px
    << "]\ncamera_model: pinhole\nintrinsics: [" << format_euroc_double(c.fx) << ", "
    << format_euroc_double(c.fy) << ", " << format_euroc_double(c.cx) << ", "
    << format_euroc_double(c.cy) << "] #fu, fv, cu, cv\ndistortion_model: " << c.distortion_model
    << "\ndistortion_coefficients: [";
  for (std::size_t i = 0; i < c.distortion.size(); ++i) {
    s << (i ? ", " : "") << format_euroc_double(c.distortion[i]);
  }
  s << "]\n";
  return s.str();
}

void write_camera_sensor_yaml(const fs::path& path, const CameraCalibration& c) {
  write_text_file(path, format_camera_sensor_yaml(c));
}

std::string format_imu_sensor_yaml(const ImuCalibration& c) {
  std::ostringstream s;
  s << "%YAML:1.0\nsensor_type: imu\ncomment: written by wallar\n\n"
    << format_T_BS(c.T_body_imu) << "rate_hz: " << format_euroc_double(c.rate_hz)
    << "\n\n# inertial sensor noise model parameters (static)\n"
    << "gyroscope_noise_density: " << format_euroc_double(c.gyro_noise_density)
    << "     # [ rad / s / sqrt(Hz) ]\n"
    << "gyroscope_random_walk: " << format_euroc_double(c.gyro_random_walk)
    << "       # [ rad / s^2 / sqrt(Hz) ]\n"
    << "accelerometer_noise_density: " << format_euroc_double(c.accel_noise_density)
    << "  # [ m / s^2 / sqrt(Hz) ]\n"
    << "accelerometer_random_walk: " << format_euroc_double(c.accel_random_walk)
    << "    # [ m / s^3 / sqrt(Hz) ]\n";
  if (c.timeshift_cam_imu_ns != 0) {
    s << "\n# camera-IMU time offset (Kalibr): t_imu = t_cam + timeshift_cam_imu [s]\n"
      << "timeshift_cam_imu: " << format_euroc_double(ns_to_s(c.timeshift_cam_imu_ns)) << "\n";
  }
  if (const std::string extra = detail::format_imu_intrinsics(c, ""); !extra.empty()) {
    s << "\n# accelerometer bias and magnetometer iron (wallar calibrate accel-mag)\n" << extra;
  }
  return s.str();
}

void write_imu_sensor_yaml(const fs::path& path, const ImuCalibration& c) {
  write_text_file(path, format_imu_sensor_yaml(c));
}

EurocWriter::EurocWriter(const fs::path& root, const RigCalibration& rig,
                         const EurocWriterOptions& options)
    : mav0_(root / "mav0"), options_(options) {
  std::error_code ec;
  for (const char* sub : {"cam0/data", "cam1/data", "imu0"}) {
    fs::create_directories(mav0_ / sub, ec);
    if (ec) throw_input_error((mav0_ / sub).string(), 0, "cannot create folder: " + ec.message());
  }
  write_text_file(mav0_ / "body.yaml", "%YAML:1.0\ncomment: wallar headset rig\n");
  for (int i = 0; i < 2; ++i) {
    const fs::path dir = mav0_ / ("cam" + std::to_string(i));
    write_camera_sensor_yaml(dir / "sensor.yaml", rig.cams[static_cast<std::size_t>(i)]);
    cam_fd_[static_cast<std::size_t>(i)] = open_csv(dir / "data.csv", kCamHeader);
  }
  // A vision-only rig (no IMU rate) gets no imu0/sensor.yaml: read_euroc takes an imu0 folder
  // with a header-only data.csv and no sensor.yaml as a recording without an IMU.
  if (rig.imu.rate_hz > 0.0) write_imu_sensor_yaml(mav0_ / "imu0" / "sensor.yaml", rig.imu);
  imu_fd_ = open_csv(mav0_ / "imu0" / "data.csv", kImuHeader);
}

EurocWriter::~EurocWriter() {
  try {
    close();
  } catch (const InputError& e) {
    std::fprintf(stderr, "wallar: closing recording: %s\n", e.what());
  }
}

void EurocWriter::write_imu(const ImuSample& s) {
  if (closed_) throw_input_error(mav0_.string(), 0, "recording already closed");
  std::string row = std::to_string(s.t_ns);
  // Appended piecewise: `"," + string` trips a false -Wrestrict in GCC 12 at -O3.
  for (const Eigen::Vector3d* v : {&s.gyro_rad_s, &s.accel_m_s2}) {
    for (int i = 0; i < 3; ++i) {
      row += ',';
      row += format_euroc_double((*v)[i]);
    }
  }
  row += '\n';
  write_all(imu_fd_, row, mav0_ / "imu0" / "data.csv");
  bytes_ += row.size();
  ++imu_rows_;
  if (s.mag_uT) {
    // The magnetometer beside imu0 (EuRoC has no place for it), stamped with its sample's time.
    const fs::path mag_csv = mav0_ / "mag0" / "data.csv";
    if (mag_fd_ < 0) {
      std::error_code ec;
      fs::create_directories(mav0_ / "mag0", ec);
      if (ec)
        throw_input_error((mav0_ / "mag0").string(), 0, "cannot create folder: " + ec.message());
      mag_fd_ = open_csv(mag_csv, kMagHeader);
    }
    std::string mag_row = std::to_string(s.t_ns);
    for (int i = 0; i < 3; ++i) {
      mag_row += ',';
      mag_row += format_euroc_double((*s.mag_uT)[i]);
    }
    mag_row += '\n';
    write_all(mag_fd_, mag_row, mag_csv);
    bytes_ += mag_row.size();
    ++mag_rows_;
  }
}

void EurocWriter::write_camera(int cam, const CameraFrame& frame) {
  if (closed_) throw_input_error(mav0_.string(), 0, "recording already closed");
  const auto idx = static_cast<std::size_t>(cam);
  const fs::path dir = mav0_ / ("cam" + std::to_string(cam));
  const std::string name = std::to_string(frame.t_ns) + ".png";
  const fs::path tmp = dir / "data" / (name + ".part");
  save_png_gray(tmp, frame.image, options_.fast_png);
  std::error_code ec;
  const std::uint64_t png_bytes = fs::file_size(tmp, ec);
  if (!ec) bytes_ += png_bytes;
  fs::rename(tmp, dir / "data" / name, ec);
  if (ec) throw_input_error(tmp.string(), 0, "cannot rename: " + ec.message());
  const std::string row = std::to_string(frame.t_ns) + "," + name + "\n";
  write_all(cam_fd_[idx], row, dir / "data.csv");
  bytes_ += row.size();
  ++cam_rows_[idx];
}

void EurocWriter::write_camera_png(int cam, TimeNs t_ns, std::span<const std::uint8_t> png) {
  if (closed_) throw_input_error(mav0_.string(), 0, "recording already closed");
  const auto idx = static_cast<std::size_t>(cam);
  const fs::path dir = mav0_ / ("cam" + std::to_string(cam));
  const std::string name = std::to_string(t_ns) + ".png";
  const fs::path tmp = dir / "data" / (name + ".part");
  write_text_file(tmp, std::string(png.begin(), png.end()), false);
  std::error_code ec;
  fs::rename(tmp, dir / "data" / name, ec);
  if (ec) throw_input_error(tmp.string(), 0, "cannot rename: " + ec.message());
  const std::string row = std::to_string(t_ns) + "," + name + "\n";
  write_all(cam_fd_[idx], row, dir / "data.csv");
  bytes_ += png.size() + row.size();
  ++cam_rows_[idx];
}

void EurocWriter::write_ground_truth(const GroundTruthState& state) {
  if (closed_) throw_input_error(mav0_.string(), 0, "recording already closed");
  const fs::path dir = mav0_ / "state_groundtruth_estimate0";
  if (gt_fd_ < 0) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw_input_error(dir.string(), 0, "cannot create folder: " + ec.message());
    const std::string header(ground_truth_csv_header());
    gt_fd_ = open_csv(dir / "data.csv", header.c_str());
  }
  const std::string row = format_ground_truth_row(state);
  write_all(gt_fd_, row, dir / "data.csv");
  bytes_ += row.size();
}

void EurocWriter::close() {
  if (closed_) return;
  closed_ = true;
  for (int* fd : {&imu_fd_, &mag_fd_, &gt_fd_, &cam_fd_[0], &cam_fd_[1]}) {
    if (*fd < 0) continue;
    ::fsync(*fd);
    ::close(*fd);
    *fd = -1;
  }
  // Make the new directory entries (renamed PNGs) durable too.
  for (const char* sub : {"cam0/data", "cam1/data", "imu0", "mag0"}) {
    const int dfd = ::open((mav0_ / sub).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
      ::fsync(dfd);
      ::close(dfd);
    }
  }
}

}  // namespace wallar::recording
