// SPDX-License-Identifier: Apache-2.0
/// @file rotating_writer.hpp
/// @brief A recording that rotates: ROOT/000001, ROOT/000002, ... each a complete EuRoC
/// recording (its own sensor files and CSVs, readable and replayable alone), or ROOT/000001.mcap,
/// ROOT/000002.mcap, ... each a complete MCAP file (`format`), a new one begun once the current
/// one holds `segment_bytes`, the oldest deleted while all of them together hold more than
/// `max_total_bytes`. A headset recording for hours fills its SD card and wears it; with a cap
/// it keeps the latest hours that fit.
///
/// A segment ends only before an IMU row or a left image, so a stereo pair never straddles two
/// segments. The segment being written is never deleted, so the cap can be exceeded by at most
/// one segment when segment_bytes is close to max_total_bytes. Deleting is the cap's purpose:
/// what a deleted segment held is counted (segments_deleted, bytes_deleted), not reported lost.
/// An MCAP segment's size counts its closed chunks (a chunk closes at chunk_bytes or 1 s of
/// log time), so a segment overshoots by up to one chunk.
///
/// Threading: one thread (the recorder's writer thread), as any RecordingWriter.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <string>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"

namespace wallar::recording {

struct RotationOptions {
  std::uint64_t segment_bytes = 0;    //!< begin a new segment at this size; 0: one segment
  std::uint64_t max_total_bytes = 0;  //!< delete the oldest segments above this; 0: keep all
  enum class Format : std::uint8_t { kEuroc, kMcap } format = Format::kEuroc;
  EurocWriterOptions writer;  //!< kEuroc
  McapRecordingOptions mcap;  //!< kMcap
};

struct RotationCounters {
  std::uint64_t segments_started = 0;
  std::uint64_t segments_deleted = 0;
  std::uint64_t bytes_deleted = 0;
  std::uint64_t delete_errors = 0;  //!< segments that could not be removed (left on disk)
};

/// The options from sizes in MiB as a command line gives them (0: not given); throws InputError
/// prefixed with `what` for a cap without a segment size or a cap under two segments.
RotationOptions rotation_from_mib(double segment_mib, double max_mib, const std::string& what);

class RotatingWriter final : public RecordingWriter {
 public:
  /// ROOT must not hold segments already (InputError naming it otherwise): a rotation never
  /// deletes what an earlier run recorded.
  RotatingWriter(std::filesystem::path root, RigCalibration rig, RotationOptions options);

  void write_imu(const ImuSample& sample) override;
  void write_camera(int cam, const CameraFrame& frame) override;
  using RecordingWriter::write_stereo;
  void close() override;

  [[nodiscard]] const RotationCounters& counters() const { return counters_; }
  /// The segments on disk, oldest first (the last one is being written until close()).
  [[nodiscard]] std::deque<std::filesystem::path> segments() const;
  /// Bytes the segments on disk hold.
  [[nodiscard]] std::uint64_t total_bytes() const;
  /// The MCAP segment being written (kMcap; null otherwise): more channels may go into it
  /// before close() (`wallar run --record`: the run's outputs in the last segment).
  [[nodiscard]] McapRecordingWriter* current_mcap() { return mcap_.get(); }

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
  std::filesystem::path current_dir_;   // the current segment (a folder, or an .mcap file)
  std::unique_ptr<EurocWriter> euroc_;  // the current segment: one of the two is open
  std::unique_ptr<McapRecordingWriter> mcap_;
  RotationCounters counters_;

  [[nodiscard]] RecordingWriter& current();
  [[nodiscard]] std::uint64_t current_bytes() const;
};

}  // namespace wallar::recording
