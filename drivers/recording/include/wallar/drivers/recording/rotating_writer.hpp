// SPDX-License-Identifier: Apache-2.0
/// @file rotating_writer.hpp
/// @brief A recording that rotates: ROOT/000001, ROOT/000002, ... each a complete EuRoC
/// recording (its own sensor files and CSVs, readable and replayable alone), a new one begun
/// once the current one holds `segment_bytes`, the oldest deleted while all of them together
/// hold more than `max_total_bytes`. A headset recording for hours fills its SD card and wears
/// it; with a cap it keeps the latest hours that fit.
///
/// A segment ends only before an IMU row or a left image, so a stereo pair never straddles two
/// segments. The segment being written is never deleted, so the cap can be exceeded by at most
/// one segment when segment_bytes is close to max_total_bytes. Deleting is the cap's purpose:
/// what a deleted segment held is counted (segments_deleted, bytes_deleted), not reported lost.
///
/// Threading: one thread (the recorder's writer thread), as any RecordingWriter.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <string>

#include "wallar/drivers/recording/euroc.hpp"

namespace wallar::recording {

struct RotationOptions {
  std::uint64_t segment_bytes = 0;    //!< begin a new segment at this size; 0: one segment
  std::uint64_t max_total_bytes = 0;  //!< delete the oldest segments above this; 0: keep all
  EurocWriterOptions writer;
};

struct RotationCounters {
  std::uint64_t segments_started = 0;
  std::uint64_t segments_deleted = 0;
  std::uint64_t bytes_deleted = 0;
  std::uint64_t delete_errors = 0;  //!< segments that could not be removed (left on disk)
};

class RotatingEurocWriter final : public RecordingWriter {
 public:
  /// ROOT must not hold segments already (InputError naming it otherwise): a rotation never
  /// deletes what an earlier run recorded.
  RotatingEurocWriter(std::filesystem::path root, RigCalibration rig, RotationOptions options);

  void write_imu(const ImuSample& sample) override;
  void write_camera(int cam, const CameraFrame& frame) override;
  using RecordingWriter::write_stereo;
  void close() override;

  [[nodiscard]] const RotationCounters& counters() const { return counters_; }
  /// The segments on disk, oldest first (the last one is being written until close()).
  [[nodiscard]] std::deque<std::filesystem::path> segments() const;
  /// Bytes the segments on disk hold.
  [[nodiscard]] std::uint64_t total_bytes() const;

 private:
  void rotate_if_full();
  void start_segment();
  void enforce_cap();

  struct Closed {
    std::filesystem::path dir;
    std::uint64_t bytes = 0;
  };
  std::filesystem::path root_;
  RigCalibration rig_;
  RotationOptions options_;
  std::deque<Closed> closed_;
  std::uint64_t closed_bytes_ = 0;
  std::filesystem::path current_dir_;
  std::unique_ptr<EurocWriter> current_;
  RotationCounters counters_;
};

}  // namespace wallar::recording
