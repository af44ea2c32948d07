// SPDX-License-Identifier: Apache-2.0
/// @file euroc.hpp
/// @brief Sensor recordings in the EuRoC/ASL layout: reader, writer and calibration files.
///
/// Layout (what Kalibr, Basalt, ORB-SLAM3 and OpenVINS read):
///   ROOT/mav0/body.yaml
///   ROOT/mav0/cam{0,1}/data.csv      "#timestamp [ns],filename"
///   ROOT/mav0/cam{0,1}/data/T.png    8-bit gray
///   ROOT/mav0/cam{0,1}/sensor.yaml   intrinsics, distortion, T_BS, resolution, rate_hz
///   ROOT/mav0/imu0/data.csv          t, w_xyz [rad/s], a_xyz [m/s^2]
///   ROOT/mav0/imu0/sensor.yaml
///   ROOT/mav0/state_groundtruth_estimate0/data.csv  (optional) t, p, q(wxyz), v, bw, ba
///
/// The same model holds a recording read from one MCAP file (mcap_recording.hpp): its images
/// then come from a FrameStore instead of files; load_frame_gray() reads either.
///
/// Threading: EurocRecording is immutable after reading (a FrameStore may be read from any
/// thread); EurocWriter is used by one thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/core/image.hpp"
#include "wallar/core/imu_sample.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/stereo_frame.hpp"

namespace wallar::recording {

/// One row of a camera's data.csv.
struct FrameEntry {
  TimeNs t_ns = 0;
  std::string filename;         //!< relative to the camera's data/ folder
  int line = 0;                 //!< line in data.csv, for error messages
  std::size_t store_index = 0;  //!< the frame's key in EurocRecording::store, when there is one
};

/// Encoded images that do not live in files (an MCAP recording's messages).
class FrameStore {
 public:
  virtual ~FrameStore() = default;
  /// The frame's image as encoded (PNG bytes). Thread-safe. Throws InputError.
  [[nodiscard]] virtual std::vector<std::uint8_t> encoded(int cam, const FrameEntry& f) const = 0;
  /// Names the frame in error messages ("REC.mcap: /cam0 message at t=...").
  [[nodiscard]] virtual std::string describe(int cam, const FrameEntry& f) const = 0;
};

struct CameraStream {
  std::filesystem::path dir;  //!< .../mav0/camN
  CameraCalibration calib;
  std::vector<FrameEntry> frames;  //!< strictly increasing t_ns

  [[nodiscard]] std::filesystem::path image_path(const FrameEntry& f) const {
    return dir / "data" / f.filename;
  }
};

/// One ground-truth row: body pose in the world (Vicon) frame, velocity, biases.
struct GroundTruthState {
  TimeNs t_ns = 0;
  SE3d T_world_body = SE3d::Identity();
  Eigen::Vector3d vel_world_m_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias_m_s2 = Eigen::Vector3d::Zero();

  /// The world's "up" (+z, against gravity) in the body frame.
  [[nodiscard]] Eigen::Vector3d up_body() const {
    return T_world_body.linear().transpose() * Eigen::Vector3d::UnitZ();
  }
};

struct EurocRecording {
  std::filesystem::path mav0;  //!< the folder holding cam0, cam1, imu0
  std::array<CameraStream, 2> cams;
  std::vector<ImuSample> imu;  //!< strictly increasing t_ns; empty for a vision-only recording
  ImuCalibration imu_calib;
  std::vector<GroundTruthState> ground_truth;  //!< empty when the recording has none
  /// The images, when they are not files under cams[i].dir/data; null for a EuRoC folder.
  std::shared_ptr<const FrameStore> store;
  /// What the reader could not use ("" when nothing): an MCAP file cut off by power loss reads
  /// up to its last complete chunk and says so here, for the command to report.
  std::string read_note;

  [[nodiscard]] RigCalibration rig() const {
    // EuRoC's body frame is the IMU's: the cameras' T_BS place them against it.
    return RigCalibration{{cams[0].calib, cams[1].calib}, imu_calib, true};
  }
};

/// The ground-truth state nearest t_ns (the earlier one on a tie), or null when the recording
/// has no ground truth.
const GroundTruthState* nearest_ground_truth(const EurocRecording& rec, TimeNs t_ns);

/// The ground-truth state at t_ns, interpolated between the two rows around it (position,
/// velocity and biases linearly, attitude by slerp), or null when t_ns lies outside the ground
/// truth's time span or more than `max_gap_ns` from a row. O(log n) per call.
std::optional<GroundTruthState> ground_truth_at(const std::vector<GroundTruthState>& ground_truth,
                                                TimeNs t_ns, DurationNs max_gap_ns = kNsPerS);

struct ReadOptions {
  /// Check that every image file named in data.csv exists (stat only, no decoding).
  bool check_image_files = true;
};

/// Reads a recording from ROOT or ROOT/mav0: cam0 and cam1 are required; imu0 is optional (a
/// vision-only recording has no imu0 folder or a data.csv of its header only: `imu` stays empty
/// and `imu_calib` the identity). A magnetometer (wallar's mav0/mag0/data.csv: timestamp [ns],
/// m_x, m_y, m_z [uT], beside EuRoC's folders) goes into the `mag_uT` of the first IMU sample at
/// or after each row (within 50 ms). Throws InputError naming the file and line of the
/// first problem: missing folder or file, short or malformed row, non-numeric field,
/// non-monotonic or duplicate timestamps, missing calibration key, wrong matrix size.
EurocRecording read_euroc(const std::filesystem::path& root, const ReadOptions& options = {});

/// Reads only the inertial part of a recording in ROOT or ROOT/mav0: imu0/data.csv (required),
/// imu0/sensor.yaml, mag0/data.csv, camN/sensor.yaml (calibration only, no frames) and the
/// ground truth, each when present. For IMU-only recordings and for tools that need no images;
/// `cams[i].frames` stay empty. Throws InputError as read_euroc does.
EurocRecording read_euroc_imu(const std::filesystem::path& root);

/// The encoded (PNG) bytes of one frame, from its file or from the recording's store.
std::vector<std::uint8_t> load_frame_encoded(const EurocRecording& rec, int cam,
                                             const FrameEntry& f);
/// One frame as 8-bit gray, checked against the camera's resolution; throws InputError.
Image load_frame_gray(const EurocRecording& rec, int cam, const FrameEntry& f);

/// Parses one CSV of each kind (exposed for tests and fuzzing). `name` appears in errors.
std::vector<FrameEntry> parse_camera_csv(std::string_view text, const std::string& name);
std::vector<ImuSample> parse_imu_csv(std::string_view text, const std::string& name);
std::vector<GroundTruthState> parse_ground_truth_csv(std::string_view text,
                                                     const std::string& name);

/// The header line of state_groundtruth_estimate0/data.csv, EuRoC's column names (with '\n').
std::string_view ground_truth_csv_header();
/// One row of that file (with '\n'): t, p, q (w >= 0), v, gyro bias, accel bias, doubles as
/// format_euroc_double writes them; parse_ground_truth_csv reads it back.
std::string format_ground_truth_row(const GroundTruthState& state);

/// Checks that every frame of each camera has a partner in the other within `tolerance_ns`;
/// throws InputError "CAMDIR/data.csv:LINE: left frame T has no right frame within X ms" for the
/// first that has none (a strict check; replay itself counts such frames and goes on).
void check_stereo_pairs(const EurocRecording& rec, DurationNs tolerance_ns);

/// Reads sensor.yaml files (EuRoC's own, which is OpenCV-flavoured YAML).
CameraCalibration read_camera_sensor_yaml(const std::filesystem::path& path);
ImuCalibration read_imu_sensor_yaml(const std::filesystem::path& path);
CameraCalibration parse_camera_sensor_yaml(std::string_view text, const std::string& name);
ImuCalibration parse_imu_sensor_yaml(std::string_view text, const std::string& name);

/// Loads an 8-bit gray PNG into a fresh buffer. Throws InputError when the file is missing,
/// unreadable, or (when expected sizes are > 0) not expected_width x expected_height.
Image load_png_gray(const std::filesystem::path& path, int expected_width = 0,
                    int expected_height = 0);
/// Loads a PNG as 8-bit RGB (gray converted, alpha composed on black); throws InputError when
/// the file is missing or unreadable.
Image load_png_rgb(const std::filesystem::path& path);
/// Writes an 8-bit gray image as PNG; throws InputError on failure. `fast`: zlib level 1
/// (about 6x faster to write on camera images, files about 15 % larger).
void save_png_gray(const std::filesystem::path& path, const Image& image, bool fast = false);
/// Writes an 8-bit gray or RGB image as PNG; throws InputError on failure.
void save_png(const std::filesystem::path& path, const Image& image, bool fast = false);
/// Decodes an 8-bit gray PNG held in memory; errors name `name`.
Image decode_png_gray(std::span<const std::uint8_t> bytes, const std::string& name,
                      int expected_width = 0, int expected_height = 0);
/// Encodes an 8-bit gray image as PNG in memory, fast (zlib level 1, as save_png_gray's fast).
std::vector<std::uint8_t> encode_png_gray(const Image& image, const std::string& name);
/// Encodes an 8-bit RGB image as PNG in memory (for writers that place the file themselves,
/// e.g. atomically); throws InputError naming `name` on failure.
std::vector<std::uint8_t> encode_png_rgb(const Image& image, const std::string& name);

/// Writes a recording in the EuRoC layout as samples arrive. Every image is written to a
/// temporary name, then renamed, before its CSV row is appended and flushed, so a recording
/// cut off by power loss is still readable up to its last complete row. close() fsyncs.
struct EurocWriterOptions {
  /// Write PNGs for speed over size (save_png_gray's `fast`): for generated recordings written
  /// in bulk, where compression would take longer than making the image.
  bool fast_png = false;
};

/// Where recorded samples go: one EuRoC recording (EurocWriter) or a rotation of them
/// (RotatingWriter, rotating_writer.hpp). Threading: one thread uses a writer.
class RecordingWriter {
 public:
  virtual ~RecordingWriter() = default;
  virtual void write_imu(const ImuSample& sample) = 0;
  virtual void write_camera(int cam, const CameraFrame& frame) = 0;
  void write_stereo(const StereoFrame& frame) {
    write_camera(0, frame.left);
    write_camera(1, frame.right);
  }
  /// Flushes and fsyncs every file; further writes are errors.
  virtual void close() = 0;
};

class EurocWriter final : public RecordingWriter {
 public:
  /// Creates ROOT/mav0/... and writes body.yaml and the sensor.yaml files.
  EurocWriter(const std::filesystem::path& root, const RigCalibration& rig,
              const EurocWriterOptions& options = {});
  ~EurocWriter();
  EurocWriter(const EurocWriter&) = delete;
  EurocWriter& operator=(const EurocWriter&) = delete;

  void write_imu(const ImuSample& sample) override;
  void write_camera(int cam, const CameraFrame& frame) override;
  using RecordingWriter::write_stereo;
  /// A frame already encoded as PNG (copied from another recording, byte for byte).
  void write_camera_png(int cam, TimeNs t_ns, std::span<const std::uint8_t> png);
  /// One row of state_groundtruth_estimate0/data.csv (the file is made on the first row).
  void write_ground_truth(const GroundTruthState& state);
  void close() override;

  [[nodiscard]] std::size_t imu_written() const { return imu_rows_; }
  /// Magnetometer rows (mav0/mag0/data.csv, made on the first sample that carries one).
  [[nodiscard]] std::size_t mag_written() const { return mag_rows_; }
  [[nodiscard]] std::size_t frames_written(int cam) const { return cam_rows_[cam]; }
  /// Bytes of rows and images written (the small sensor files aside).
  [[nodiscard]] std::uint64_t bytes_written() const { return bytes_; }
  [[nodiscard]] const std::filesystem::path& mav0() const { return mav0_; }

 private:
  std::filesystem::path mav0_;
  EurocWriterOptions options_;
  int imu_fd_ = -1;                    //!< imu0/data.csv, O_APPEND
  int gt_fd_ = -1;                     //!< state_groundtruth_estimate0/data.csv, once needed
  int mag_fd_ = -1;                    //!< mag0/data.csv, once a sample carries the field
  std::array<int, 2> cam_fd_{-1, -1};  //!< camN/data.csv, O_APPEND
  std::size_t imu_rows_ = 0;
  std::size_t mag_rows_ = 0;
  std::array<std::size_t, 2> cam_rows_{0, 0};
  std::uint64_t bytes_ = 0;
  bool closed_ = false;
};

/// Writes EuRoC sensor.yaml files (readable by read_*_sensor_yaml and by Kalibr/Basalt tools).
void write_camera_sensor_yaml(const std::filesystem::path& path, const CameraCalibration& calib);
void write_imu_sensor_yaml(const std::filesystem::path& path, const ImuCalibration& calib);
/// The same files' text (parse_*_sensor_yaml reads it back exactly).
std::string format_camera_sensor_yaml(const CameraCalibration& calib);
std::string format_imu_sensor_yaml(const ImuCalibration& calib);

}  // namespace wallar::recording
