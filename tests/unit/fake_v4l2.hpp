// SPDX-License-Identifier: Apache-2.0
/// @file fake_v4l2.hpp
/// @brief A fake V4L2 device behind the driver's system-call seam, with fault injection.
///
/// It implements the ioctls the driver uses (QUERYCAP, S_FMT, G_PARM/S_PARM, G_CTRL, REQBUFS,
/// QUERYBUF, QBUF, DQBUF, STREAMON, STREAMOFF) on the same structures the kernel receives, hands
/// out mmap pointers into its own buffer memory, and answers poll() like vb2 does (POLLIN when
/// a buffer is done, POLLERR when not streaming, POLLERR|POLLHUP after an unplug).
///
/// Time is virtual: now_ns() is a counter that only poll() advances. A streaming device makes a
/// frame every period (plus its phase); poll() jumps the clock to the next frame or to the end
/// of its timeout, so tests of stalls and retries run in microseconds and are deterministic.
/// Triggered devices make a frame only when trigger() is called.
///
/// Faults: a stall (until the next STREAMON, or until cleared), the next N DQBUFs answering
/// EAGAIN, an errno for the next N calls of one ioctl, EINTR on ioctls or polls, an unplug
/// (open fails with ENOENT, every call on an open fd with ENODEV) and replug, sequence jumps and
/// repeats, repeated timestamps, error-flagged and short buffers, another timestamp source.
///
/// Allocation: REQBUFS and mmap allocate; steady-state streaming (QBUF/DQBUF/poll/produce) does
/// not, except for MJPG frames (encoded with libjpeg).
///
/// Threading: one thread drives it (the capture thread and the test, in turn); munmap and close
/// may also come from the thread that drops the last frame of a closed device, so the mapping
/// table is guarded by a mutex.
#pragma once

#include <linux/videodev2.h>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "wallar/core/mailbox.hpp"
#include "wallar/drivers/camera/stereo_capture.hpp"
#include "wallar/drivers/camera/v4l2_system.hpp"

namespace wallar::test {

struct FakeCameraSpec {
  std::vector<std::uint32_t> fourccs{V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
  int width_px = 64;
  int height_px = 48;
  double fps = 30.0;
  bool can_set_fps = true;
  std::uint32_t caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  std::uint32_t timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
  std::int32_t exposure_100us = 0;  //!< 0: V4L2_CID_EXPOSURE_ABSOLUTE unsupported
  DurationNs phase_ns = 0;          //!< offset of this device's frame times
  bool triggered = false;           //!< frames only on trigger()
  int max_buffers = 32;
  /// Draw the test pattern into every frame; when false (benchmarks) the buffers keep the first
  /// frame's pixels, and MJPG frames are the first frame's encoding.
  bool render_every_frame = true;
};

class FakeV4l2;

class FakeV4l2Device {
 public:
  FakeV4l2Device(FakeV4l2& sys, std::string path, FakeCameraSpec spec);

  // ---- faults -----------------------------------------------------------------------------
  void set_stalled(bool stalled) { stalled_ = stalled; }
  void stall_until_restart() { stall_until_streamon_ = true; }
  void eagain_storm(int count) { eagain_left_ = count; }
  /// The next `count` calls of `request` fail with `err`.
  void fail_next(unsigned long request, int err, int count = 1);  // NOLINT(google-runtime-int)
  void unplug();
  /// A fatal streaming error (vb2_queue_error, as vivid's "Inject Fatal Streaming Error"):
  /// POLLERR and DQBUF fails with EIO until the stream is turned off.
  void queue_error() { queue_error_ = true; }
  void replug() { present_ = true; }
  void jump_sequence(int delta) { sequence_ += static_cast<std::uint32_t>(delta); }
  void repeat_next_timestamp() { repeat_timestamp_ = true; }
  void flag_next_error() { error_next_ = true; }
  void short_next() { short_next_ = true; }
  void corrupt_next_jpeg() { corrupt_jpeg_next_ = true; }
  void set_timestamp_flags(std::uint32_t flags) { spec_.timestamp_flags = flags; }

  // ---- observation ------------------------------------------------------------------------
  [[nodiscard]] bool streaming() const { return streaming_; }
  [[nodiscard]] int queued() const { return queued_count_; }
  [[nodiscard]] int buffers() const { return buffer_count_; }
  [[nodiscard]] std::uint64_t produced() const { return produced_; }
  [[nodiscard]] std::uint64_t lost() const { return lost_; }  //!< no buffer was queued
  [[nodiscard]] int streamons() const { return streamons_; }
  [[nodiscard]] int opens() const { return opens_; }
  [[nodiscard]] const std::string& path() const { return path_; }
  /// Pixel memory of buffer `index` of the current queue (zero-copy checks).
  [[nodiscard]] const std::uint8_t* buffer_memory(int index) const;
  /// The gray level the pattern has at (x, y) of frame number `frame`.
  static std::uint8_t pattern(std::uint64_t frame, int x, int y) {
    return static_cast<std::uint8_t>((x * 3 + y * 5 + frame * 7) & 0xFF);
  }

  // ---- used by FakeV4l2 -------------------------------------------------------------------
  int ioctl(int fd, unsigned long request, void* arg);  // NOLINT(google-runtime-int)
  void produce(TimeNs t_ns);
  [[nodiscard]] short revents() const;
  [[nodiscard]] TimeNs next_frame_ns() const;  //!< INT64_MAX when none is due
  [[nodiscard]] bool present() const { return present_; }
  void on_close(int fd);

 private:
  struct Queue;  // one REQBUFS generation: buffers that stay valid while mapped
  friend class FakeV4l2;

  FakeV4l2& sys_;
  std::string path_;
  FakeCameraSpec spec_;
  int owner_fd_ = -1;  //!< the fd that allocated buffers
  std::uint32_t fourcc_ = 0;
  std::shared_ptr<Queue> queue_;
  int buffer_count_ = 0;
  std::array<int, 32> queued_{};  // FIFO of queued buffer indices
  int queued_head_ = 0, queued_count_ = 0;
  std::array<int, 32> done_{};
  int done_head_ = 0, done_count_ = 0;
  bool streaming_ = false;
  bool queue_error_ = false;
  bool present_ = true;
  bool stalled_ = false;
  bool stall_until_streamon_ = false;
  bool repeat_timestamp_ = false, error_next_ = false, short_next_ = false;
  bool corrupt_jpeg_next_ = false;
  std::vector<std::uint8_t> first_jpeg_;  //!< render_every_frame == false
  int eagain_left_ = 0;
  unsigned long fail_request_ = 0;  // NOLINT(google-runtime-int)
  int fail_errno_ = 0, fail_left_ = 0;
  std::uint32_t sequence_ = 0;
  std::uint64_t produced_ = 0, lost_ = 0;
  TimeNs next_frame_ns_ = 0;
  TimeNs last_stamp_ns_ = 0;
  int streamons_ = 0, opens_ = 0;
  double fps_;
};

class FakeV4l2 final : public drivers::V4l2System {
 public:
  FakeV4l2();
  ~FakeV4l2() override;
  FakeV4l2Device& add_device(const std::string& path, FakeCameraSpec spec = {});
  /// Makes every triggered device expose a frame now.
  void trigger();
  void interrupt_next_ioctls(int count) { eintr_ioctls_ = count; }
  void interrupt_next_polls(int count) { eintr_polls_ = count; }
  void advance(DurationNs dt_ns) { now_ns_ += dt_ns; }
  [[nodiscard]] int open_fds() const;
  [[nodiscard]] int mappings() const;

  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;  // NOLINT(google-runtime-int)
  void* mmap(std::size_t length, int prot, int flags, int fd, off_t offset) override;
  int munmap(void* addr, std::size_t length) override;
  int poll(pollfd* fds, nfds_t count, int timeout_ms) override;
  TimeNs now_ns() override { return now_ns_; }

 private:
  friend class FakeV4l2Device;
  FakeV4l2Device* device_of(int fd);

  std::vector<std::unique_ptr<FakeV4l2Device>> devices_;
  std::array<FakeV4l2Device*, 64> fds_{};  // fd - kFirstFd -> device
  mutable std::mutex mutex_;               // mappings_ and fds_ (munmap/close off-thread)
  std::map<const void*, std::shared_ptr<void>> mappings_;
  TimeNs now_ns_ = 1000 * kNsPerS;
  int eintr_ioctls_ = 0, eintr_polls_ = 0;
};

/// Capture's sink toward the tracker: each pair posted to a newest-only mailbox.
class MailboxSink final : public source::SensorSink {
 public:
  void on_imu(const ImuSample&) override {}
  void on_stereo(const StereoFrame& frame) override { box.post(frame); }
  NewestMailbox<StereoFrame> box;
};

/// A trigger line wired to every triggered fake device.
class FakeTrigger final : public drivers::TriggerOutput {
 public:
  explicit FakeTrigger(FakeV4l2& sys) : sys_(sys) {}
  void set(bool asserted) override {
    if (asserted && !level_) {
      sys_.trigger();
      ++rises;
    }
    level_ = asserted;
  }
  int rises = 0;

 private:
  FakeV4l2& sys_;
  bool level_ = false;
};

}  // namespace wallar::test
