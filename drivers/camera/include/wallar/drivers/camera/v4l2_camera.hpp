// SPDX-License-Identifier: Apache-2.0
/// @file v4l2_camera.hpp
/// @brief One V4L2 capture device: format negotiation, mmap streaming, kernel timestamps,
/// dropped-frame detection, zero-copy frames, and recovery from stalls and disconnects.
///
/// Start-up (`start()`): open O_RDWR|O_NONBLOCK, VIDIOC_QUERYCAP (video capture + streaming
/// I/O), VIDIOC_S_FMT (the driver may answer with another format: that is a refusal, named in
/// the error), VIDIOC_S_PARM (frame rate, read back), VIDIOC_REQBUFS + QUERYBUF + mmap for
/// `buffer_count` buffers, QBUF all, STREAMON.
///
/// Running (`step()`, a non-blocking state machine driven by the capture thread after poll):
/// DQBUF until EAGAIN, each buffer checked (V4L2_BUF_FLAG_ERROR, bytesused), stamped, and its
/// sequence number compared with the last: a gap of n is n dropped frames, a repeated or
/// backward number is a sequence error. Frames are delivered as counted references:
///   - GREY: zero-copy. The Image *is* the kernel buffer; when the last reference is dropped
///     (on any thread) the buffer is marked returned and the capture thread re-queues it
///     (QBUF) on its next step. Consumers that hold frames hold kernel buffers: hold fewer than
///     `buffer_count - 2` or the device drops frames (counted as dropped).
///   - YUYV and MJPG: converted to 8-bit gray (the luma plane; libjpeg for MJPG) into a pool
///     of `pool_size` buffers allocated at start-up; the kernel buffer is re-queued at once.
///
/// Timestamps: V4L2 buffer timestamps are CLOCK_MONOTONIC when V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC
/// is set (uvcvideo, most drivers). With V4L2_BUF_FLAG_TSTAMP_SRC_SOE they mark the start of
/// exposure and are used as they are; with TSTAMP_SRC_EOF (end of frame) the exposure time
/// (V4L2_CID_EXPOSURE_ABSOLUTE, when the driver has it) is subtracted. A driver that gives no
/// monotonic stamp gets the dequeue time minus one frame period, counted in
/// `timestamp_fallbacks`. A frame whose time does not increase is dropped (`non_monotonic`).
///
/// Recovery ladder (each rung counted, each state change reported once to the listener):
///   no frame for `stall_timeout_ns`  -> restart the stream (STREAMOFF, re-queue, STREAMON);
///   still none after `restarts_before_reopen` restarts, EIO from DQBUF that a restart does not
///   cure, or the device gone (ENODEV, POLLERR/POLLHUP) -> close and reopen the device node;
///   `reopens_before_reset` failed reopens -> a USB port reset through the reset hook (the
///   board file's VID:PID), then reopen attempts every `retry_interval_ns`, for ever.
/// Closing the device closes its fd at once (the kernel frees the queue, so a reopen can take
/// it); buffers that consumers still hold stay mapped until the last one is released.
///
/// Allocation: start() and reopening allocate; step() on a streaming GREY or YUYV camera
/// allocates nothing (MJPG: libjpeg allocates per frame, see jpeg.hpp).
///
/// Threading: one thread (the capture thread) calls start/step/stop; frames may be dropped on
/// any thread. The accessors are for that thread (or after stop()).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "wallar/core/stereo_frame.hpp"
#include "wallar/drivers/camera/v4l2_system.hpp"

struct v4l2_buffer;

namespace wallar::recording {
class JpegDecoder;
}

namespace wallar::drivers {

enum class CameraPixelFormat : std::uint8_t { kGrey, kYuyv, kMjpg };

/// "GREY", "YUYV", "MJPG" (the V4L2 four-character codes); nullopt for anything else.
std::optional<CameraPixelFormat> parse_camera_pixel_format(std::string_view text);
std::uint32_t fourcc_of(CameraPixelFormat format);
/// A four-character code as text ("YUYV"); non-printable bytes as '?'.
std::string fourcc_to_string(std::uint32_t fourcc);

/// Most buffers a camera maps (V4L2 allows 32; the returned-buffer mask is 32 bits).
inline constexpr int kMaxV4l2Buffers = 32;

struct V4l2CameraConfig {
  std::string name = "cam0";  //!< in messages: "left", "right"
  std::string device;         //!< "/dev/video0" or a /dev/v4l/by-path link
  std::string usb_id;         //!< "VID:PID" for the USB reset rung; empty = no reset
  int width_px = 640;
  int height_px = 480;
  double fps = 30.0;
  CameraPixelFormat format = CameraPixelFormat::kGrey;
  int buffer_count = 8;             //!< kernel buffers requested [2, kMaxV4l2Buffers]
  int pool_size = 6;                //!< gray buffers for converted formats [1, 32]
  DurationNs stall_timeout_ns = 0;  //!< 0: max(10 frame periods, 500 ms)
  int restarts_before_reopen = 1;
  int reopens_before_reset = 2;
  DurationNs retry_interval_ns = kNsPerS;  //!< between reopen attempts
};

enum class CameraState : std::uint8_t {
  kStopped,     //!< not started, or stopped
  kStreaming,   //!< delivering frames
  kRecovering,  //!< stalled or failed; restarting, reopening
  kDead,        //!< reset did not help; still retrying every retry_interval_ns
};
const char* to_string(CameraState state);

/// One counter per event class; all only ever increase.
struct CameraCounters {
  std::uint64_t frames = 0;               //!< delivered
  std::uint64_t dropped = 0;              //!< missing sequence numbers (device-side drops)
  std::uint64_t sequence_errors = 0;      //!< repeated or backward sequence numbers
  std::uint64_t non_monotonic = 0;        //!< frames dropped because their time did not increase
  std::uint64_t corrupt = 0;              //!< V4L2_BUF_FLAG_ERROR, short bytesused, bad MJPEG
  std::uint64_t pool_exhausted = 0;       //!< converted frames dropped: consumers hold every slot
  std::uint64_t eagain = 0;               //!< DQBUF said EAGAIN although poll said readable
  std::uint64_t eintr = 0;                //!< calls interrupted and retried
  std::uint64_t io_errors = 0;            //!< EIO from DQBUF/QBUF
  std::uint64_t timeouts = 0;             //!< stall timeouts (no frame for stall_timeout_ns)
  std::uint64_t stream_restarts = 0;      //!< STREAMOFF/STREAMON cycles
  std::uint64_t disconnects = 0;          //!< device gone (ENODEV, POLLERR/POLLHUP)
  std::uint64_t reopens = 0;              //!< successful reopen of the device node
  std::uint64_t reopen_failures = 0;      //!< failed attempts
  std::uint64_t usb_resets = 0;           //!< USB port resets requested
  std::uint64_t timestamp_fallbacks = 0;  //!< frames stamped at dequeue (no monotonic stamp)
};
/// "frames=N dropped=N ..." on one line.
std::string format_counters(const CameraCounters& c);

/// What the camera negotiated.
struct V4l2Negotiated {
  std::uint32_t fourcc = 0;
  int width_px = 0;
  int height_px = 0;
  int stride_bytes = 0;
  std::uint32_t size_bytes = 0;
  double fps = 0.0;                //!< from VIDIOC_G_PARM, or the requested rate
  int buffers = 0;                 //!< kernel buffers granted
  bool start_of_exposure = false;  //!< the driver stamps the start of exposure
  DurationNs exposure_ns = 0;      //!< subtracted from end-of-frame stamps
  std::string driver;              //!< v4l2_capability.driver ("uvcvideo")
  std::string card;                //!< v4l2_capability.card
};

/// Receives frames and state changes from V4l2Camera::step(), on the capture thread.
class CameraListener {
 public:
  virtual ~CameraListener() = default;
  virtual void on_frame(int cam, CameraFrame&& frame) = 0;
  /// A state change, reported once per transition; `reason` is a static string, `err` an
  /// errno or 0.
  virtual void on_camera_state(int cam, CameraState state, const char* reason, int err) {
    (void)cam, (void)state, (void)reason, (void)err;
  }
};

/// Resets the USB device behind a camera: (usb_id "VID:PID", device node). Returns false when
/// it could not. Called on the capture thread, at most once per `reopens_before_reset` failures.
using UsbResetHook = std::function<bool(const std::string& usb_id, const std::string& device)>;

class V4l2Camera {
 public:
  /// `index` is the camera's number in listener calls (0 = left).
  V4l2Camera(V4l2System& sys, V4l2CameraConfig config, int index, UsbResetHook reset = {});
  ~V4l2Camera();
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  /// Opens, negotiates and starts streaming. Throws DeviceError "NAME DEVICE: what: why" when
  /// the device cannot be opened, is no capture device, refuses the format, or cannot map.
  void start();
  /// STREAMOFF and close (buffers still held by consumers are unmapped when released).
  void stop();

  /// Does what is due: re-queues returned buffers, dequeues ready frames (`revents` from poll
  /// on fd(); 0 when poll was not asked or timed out), detects stalls, runs the recovery
  /// ladder. Returns the time by which it wants to be called again.
  TimeNs step(TimeNs now_ns, short revents, CameraListener& listener);

  /// The fd to poll for POLLIN (-1 while closed).
  [[nodiscard]] int fd() const;
  [[nodiscard]] CameraState state() const { return state_; }
  [[nodiscard]] const CameraCounters& counters() const { return counters_; }
  [[nodiscard]] const V4l2Negotiated& negotiated() const { return negotiated_; }
  [[nodiscard]] const V4l2CameraConfig& config() const { return config_; }
  /// Frame period from the negotiated rate [ns].
  [[nodiscard]] DurationNs period_ns() const;

  class Slots;  // shared, reference-counted buffer sets (kernel buffers, gray pool)

 private:
  enum class Rung : std::uint8_t { kRestart, kReopen };
  // open + negotiate + map + STREAMON; on failure returns the errno-like code and a static
  // reason, leaving the camera closed. `message` gets the one-line text for start().
  int open_and_stream(const char*& reason, std::string* message);
  void close_device();
  bool stream_on();
  void stream_off();
  void collect_returned();
  int queue_idle();  // QBUF every idle buffer; 0 or the errno of the first failure
  int dequeue_all(TimeNs now_ns, CameraListener& listener);
  void deliver(const ::v4l2_buffer& buf, TimeNs now_ns, CameraListener& listener);
  void set_state(CameraState s, const char* reason, int err, CameraListener& listener);
  TimeNs recover(TimeNs now_ns, Rung rung, const char* reason, int err, CameraListener& listener);
  int xioctl(unsigned long request, void* arg);  // NOLINT(google-runtime-int)

  V4l2System& sys_;
  V4l2CameraConfig config_;
  int index_;
  UsbResetHook reset_;
  int fd_ = -1;
  bool streaming_ = false;
  CameraState state_ = CameraState::kStopped;
  CameraCounters counters_;
  V4l2Negotiated negotiated_;
  Slots* kernel_ = nullptr;  //!< the open fd's mapped buffers (a counted reference)
  Slots* pool_ = nullptr;    //!< gray buffers for converted formats (a counted reference)
  // Kernel buffers: each is in exactly one of queued (kernel), out (consumers) or idle (ours).
  std::uint32_t queued_mask_ = 0;
  std::uint32_t out_mask_ = 0;
  std::uint32_t idle_mask_ = 0;
  std::uint32_t free_pool_mask_ = 0;
  std::unique_ptr<recording::JpegDecoder> jpeg_;
  std::optional<std::uint32_t> last_sequence_;
  TimeNs last_t_ns_ = 0;
  TimeNs last_progress_ns_ = 0;  //!< last frame, or (re)start of the stream
  TimeNs next_attempt_ns_ = 0;   //!< reopen attempts while recovering
  int restarts_in_row_ = 0;
  int reopens_in_row_ = 0;  //!< reopen attempts without a frame in between
  bool reset_done_ = false;
  std::string decode_error_;  //!< reused by the MJPEG path
};

}  // namespace wallar::drivers
