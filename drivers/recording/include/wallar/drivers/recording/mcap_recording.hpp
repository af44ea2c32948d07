// SPDX-License-Identifier: Apache-2.0
/// @file mcap_recording.hpp
/// @brief Sensor recordings as one MCAP file: wallar's topics and schemas, the writer that
/// `wallar record --format mcap` uses, the reader behind every command that takes a recording,
/// and the converter between MCAP and the EuRoC layout.
///
/// Layout. Messages are JSON ("json" encoding) under JSON Schemas ("jsonschema"), Foxglove's
/// where Foxglove publishes one, so Foxglove Studio and the mcap CLI open the file as it is:
///   /cam0, /cam1     foxglove.CompressedImage   timestamp, frame_id "cam0"/"cam1",
///                                               data (the PNG, base64), format "png"
///   /cam0/calibration, /cam1/calibration
///                    foxglove.CameraCalibration one beside each image, at its time: width,
///                                               height, distortion_model (plumb_bob, or
///                                               kannala_brandt for equidistant), D, K, R
///                                               (identity: raw images), P ([K | 0])
///   /imu0            wallar.Imu                 timestamp, frame_id "imu0", angular_velocity
///                                               [rad/s], linear_acceleration [m/s^2] ({x,y,z})
///   /ground_truth    wallar.GroundTruthState    (optional) timestamp, frame_id "world",
///                                               position, orientation (x,y,z,w: body in world),
///                                               velocity, gyro_bias, accel_bias
///   metadata "wallar.rig": "cam0/sensor.yaml", "cam1/sensor.yaml" and, with an IMU,
///                          "imu0/sensor.yaml": EuRoC's own calibration files, as text.
/// Every message's log_time and publish_time are the sample's t_ns (CLOCK_MONOTONIC for a
/// live recording, the source's clock for a converted one). Images are PNG, so a recording
/// converted either way keeps every pixel and gives the same trajectory.
///
/// Threading: a McapRecordingWriter is used by one thread; what the readers return is
/// immutable (its FrameStore may be read from any thread).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/mcap.hpp"

namespace wallar::recording {

struct McapRecordingOptions {
  mcap::Compression compression = mcap::Compression::kZstd;
  /// A chunk closes at this many uncompressed bytes or after 1 s of log time: the most a power
  /// loss can take from the file.
  std::uint64_t chunk_bytes = 4u << 20;
};

class McapRecordingWriter final : public RecordingWriter {
 public:
  /// Creates `path` (which must not exist) and writes the schemas, channels and calibration.
  /// `with_ground_truth`: also a /ground_truth channel.
  McapRecordingWriter(const std::filesystem::path& path, const RigCalibration& rig,
                      const McapRecordingOptions& options = {}, bool with_ground_truth = false);
  ~McapRecordingWriter() override;
  McapRecordingWriter(const McapRecordingWriter&) = delete;
  McapRecordingWriter& operator=(const McapRecordingWriter&) = delete;

  void write_imu(const ImuSample& sample) override;
  /// Encodes the frame as PNG (fast, zlib level 1).
  void write_camera(int cam, const CameraFrame& frame) override;
  using RecordingWriter::write_stereo;
  /// A frame already encoded as PNG, copied byte for byte.
  void write_camera_png(int cam, TimeNs t_ns, std::span<const std::uint8_t> png);
  void write_ground_truth(const GroundTruthState& state);
  /// Another channel of JSON messages under a JSON Schema (the firmware's outputs: Foxglove's
  /// PoseInFrame, PointCloud, SceneUpdate, ...); its id for write_json.
  std::uint16_t add_json_channel(const std::string& schema_name, const std::string& json_schema,
                                 const std::string& topic);
  void write_json(std::uint16_t channel, TimeNs t_ns, const std::string& json);
  void close() override;

  [[nodiscard]] std::size_t imu_written() const { return imu_; }
  [[nodiscard]] std::size_t frames_written(int cam) const {
    return frames_[static_cast<std::size_t>(cam)];
  }
  [[nodiscard]] std::uint64_t bytes_written() const { return writer_->bytes_written(); }

 private:
  std::filesystem::path path_;
  std::unique_ptr<mcap::Writer> writer_;
  std::array<std::uint16_t, 2> cam_channel_{};
  std::array<std::uint16_t, 2> calibration_channel_{};  //!< /camN/calibration
  std::array<std::string, 2> calibration_members_;      //!< its JSON after the timestamp
  std::uint16_t imu_channel_ = 0;
  std::uint16_t gt_channel_ = 0;
  bool with_ground_truth_ = false;
  std::size_t imu_ = 0;
  std::array<std::size_t, 2> frames_{0, 0};
};

/// base64 (RFC 4648, padded): how JSON Schema's contentEncoding carries bytes in JSON
/// messages (images here, Foxglove's point clouds). decode: false on a character outside the
/// alphabet or a bad length or padding.
std::string base64_encode(std::span<const std::uint8_t> in);
bool base64_decode(std::string_view in, std::vector<std::uint8_t>& out);

/// True when `path` is a file that starts with MCAP's magic bytes.
bool is_mcap_recording(const std::filesystem::path& path);

/// Reads a recording written in the layout above. A file cut short reads up to its last
/// complete chunk and says what was lost in `read_note`. Throws InputError naming the file
/// (and the message) for anything else: not MCAP, no /cam0 or /cam1, no "wallar.rig"
/// calibration, a message that does not parse under its schema, two frames at one time.
/// `require_cameras` false: an inertial-only file (no /cam0, /cam1) reads too.
EurocRecording read_mcap_recording(const std::filesystem::path& path, bool require_cameras = true);

/// A EuRoC folder (read_euroc) or an MCAP file (read_mcap_recording), told apart by content.
EurocRecording read_recording(const std::filesystem::path& path, const ReadOptions& options = {});
/// The inertial part of either (read_euroc_imu, or an MCAP file with or without cameras).
EurocRecording read_recording_imu(const std::filesystem::path& path);

struct ConvertCounts {
  std::array<std::size_t, 2> frames{0, 0};
  std::size_t imu = 0;
  std::size_t ground_truth = 0;
  std::uint64_t bytes_written = 0;
};

/// Every stream of `rec` (frames as encoded, IMU, ground truth when the writer has its channel)
/// into `writer`, in time order; the writer stays open.
ConvertCounts write_streams(const EurocRecording& rec, McapRecordingWriter& writer);

/// Writes `rec` (read by read_recording) to `out`: an MCAP file when `to_mcap`, else a EuRoC
/// folder. Images are copied as encoded; every stream keeps its samples and times. Refuses an
/// existing `out` (a file, or a folder holding mav0/).
ConvertCounts convert_recording(const EurocRecording& rec, const std::filesystem::path& out,
                                bool to_mcap, const McapRecordingOptions& options = {});

}  // namespace wallar::recording
