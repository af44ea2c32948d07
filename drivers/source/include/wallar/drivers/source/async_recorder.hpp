// SPDX-License-Identifier: Apache-2.0
/// @file async_recorder.hpp
/// @brief The recorder's bounded writer thread: the capture and IMU threads hand their samples
/// to it through two lock-free rings and never wait for the disk.
///
/// Two SPSC rings, one per producer thread: IMU samples, and camera frames (a stereo pair is
/// one slot holding both eyes, an unpaired frame a slot with one eye). Every slot is allocated
/// at construction. With copy_frames the producer copies the pixels into the slot's own buffer
/// (sized for the board's images), so a live frame's V4L2 buffer goes back to the driver at
/// once; a frame that does not fit is kept by reference instead (counted, never lost). A full
/// ring drops the sample and counts it (per stream); nothing blocks unless wait_when_full is
/// set (replay, where waiting loses nothing).
///
/// The writer thread ("recorder") drains both rings into a RecordingWriter in time order (the
/// older ring head first, IMU first on ties; a head that is alone is written at once, so the
/// merge does not wait for a late stream) and sleeps ~2 ms when both are empty. The first write
/// failure (disk full, EIO, ...) is kept as one line; from then on the writer writes nothing
/// more (the recording stays readable up to its last complete row) but keeps draining and
/// counting what it discards, so the producers never stall.
///
/// Threading: on_imu()/on_imu_sample() are called from one thread (the IMU producer) and
/// on_stereo()/on_unpaired() from one thread (the frame producer; it may be the same thread).
/// They do not block (unless wait_when_full), allocate or throw. counters() may be called from
/// any thread at any time (each counter is read atomically; the set is not one snapshot).
/// close() and the destructor belong to the owning thread; samples that arrive after close()
/// began are dropped and counted. The writer is used by the writer thread only, from
/// construction until close() returns, and must outlive the recorder.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "wallar/drivers/imu/imu_driver.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/source/sensor_sink.hpp"

namespace wallar::source {

struct AsyncRecorderOptions {
  std::size_t imu_capacity = 16384;  //!< IMU samples the ring holds (80 s at 200 Hz)
  std::size_t frame_capacity = 16;   //!< frame slots (a stereo pair or one unpaired frame)
  /// Copy each frame's pixels into a slot buffer on the producer thread (the source's buffer is
  /// released at once); false keeps a counted reference to the source's image.
  bool copy_frames = true;
  /// Per camera (left, right): the image size the slot buffers are made for (gray, 1 byte per
  /// pixel). A frame with more bytes than that is kept by reference (frames_not_copied).
  std::array<int, 2> width_px{640, 640};
  std::array<int, 2> height_px{480, 480};
  /// Wait (sleeping briefly) for room instead of dropping when a ring is full. For producers
  /// that can afford to wait, such as replay; live sources keep this false.
  bool wait_when_full = false;
  /// close() closes the writer (flush, fsync). False leaves it open for the owner, who may add
  /// to it once close() returned and closes it itself (`wallar run --record`: the run's
  /// outputs after its sensor streams).
  bool close_writer = true;
};

/// What the recorder did. A sample is in exactly one of: written, dropped, write_errors.
struct RecorderCounters {
  std::uint64_t imu_written = 0;                  //!< IMU rows in the recording
  std::array<std::uint64_t, 2> frames_written{};  //!< image rows in the recording, per camera
  std::uint64_t pairs_written = 0;                //!< stereo pairs with both eyes written
  std::uint64_t imu_dropped = 0;                  //!< IMU samples refused: ring full or closed
  std::uint64_t frames_dropped = 0;               //!< camera frames refused (a pair counts 2)
  std::uint64_t imu_high_water = 0;               //!< most IMU samples ever waiting
  std::uint64_t frame_high_water = 0;             //!< most frame slots ever waiting
  /// Samples + frames lost to a write failure: the one whose write failed and all after it.
  std::uint64_t write_errors = 0;
  std::uint64_t frames_not_copied = 0;  //!< frames kept by reference: too big for the slot
  std::string error;                    //!< the first write failure, one line; empty if none

  /// IMU samples and camera frames that are not in the recording.
  [[nodiscard]] std::uint64_t lost() const { return imu_dropped + frames_dropped + write_errors; }
};

class AsyncRecorder final : public SensorSink, public drivers::ImuSampleSink {
 public:
  /// Allocates the rings (and slot buffers) and starts the writer thread.
  explicit AsyncRecorder(recording::RecordingWriter& writer,
                         const AsyncRecorderOptions& options = {});
  /// Closes (drains, fsyncs, joins) if close() was not called.
  ~AsyncRecorder() override;
  AsyncRecorder(const AsyncRecorder&) = delete;
  AsyncRecorder& operator=(const AsyncRecorder&) = delete;

  void on_imu(const ImuSample& sample) override;
  void on_imu_sample(const ImuSample& sample) noexcept override;
  void on_stereo(const StereoFrame& frame) override;
  void on_unpaired(int cam, const CameraFrame& frame) override;

  /// Stops accepting, writes everything still queued, closes the writer (fsync), joins the
  /// writer thread and returns the final counters. Later calls return the same counters.
  RecorderCounters close();

  [[nodiscard]] RecorderCounters counters() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace wallar::source
