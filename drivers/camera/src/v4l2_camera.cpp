// SPDX-License-Identifier: Apache-2.0
/// @file v4l2_camera.cpp
/// @brief V4L2 mmap streaming capture; see v4l2_camera.hpp for the contract.
#include "wallar/drivers/camera/v4l2_camera.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/jpeg.hpp"

namespace wallar::drivers {

// ---------------------------------------------------------------------------------------------
// Formats

std::optional<CameraPixelFormat> parse_camera_pixel_format(std::string_view text) {
  if (text == "GREY") return CameraPixelFormat::kGrey;
  if (text == "YUYV") return CameraPixelFormat::kYuyv;
  if (text == "MJPG") return CameraPixelFormat::kMjpg;
  return std::nullopt;
}

std::uint32_t fourcc_of(CameraPixelFormat format) {
  switch (format) {
    case CameraPixelFormat::kGrey:
      return V4L2_PIX_FMT_GREY;
    case CameraPixelFormat::kYuyv:
      return V4L2_PIX_FMT_YUYV;
    case CameraPixelFormat::kMjpg:
      return V4L2_PIX_FMT_MJPEG;
  }
  return 0;
}

std::string fourcc_to_string(std::uint32_t fourcc) {
  std::string s(4, '?');
  for (int i = 0; i < 4; ++i) {
    const auto c = static_cast<char>((fourcc >> (8 * i)) & 0xFFu);
    if (c >= 0x20 && c < 0x7F) s[static_cast<std::size_t>(i)] = c;
  }
  return s;
}

const char* to_string(CameraState state) {
  switch (state) {
    case CameraState::kStopped:
      return "stopped";
    case CameraState::kStreaming:
      return "streaming";
    case CameraState::kRecovering:
      return "recovering";
    case CameraState::kDead:
      return "dead";
  }
  return "?";
}

std::string format_counters(const CameraCounters& c) {
  const std::pair<const char*, std::uint64_t> fields[] = {
      {"frames", c.frames},
      {"dropped", c.dropped},
      {"sequence_errors", c.sequence_errors},
      {"non_monotonic", c.non_monotonic},
      {"corrupt", c.corrupt},
      {"pool_exhausted", c.pool_exhausted},
      {"eagain", c.eagain},
      {"eintr", c.eintr},
      {"io_errors", c.io_errors},
      {"timeouts", c.timeouts},
      {"stream_restarts", c.stream_restarts},
      {"disconnects", c.disconnects},
      {"reopens", c.reopens},
      {"reopen_failures", c.reopen_failures},
      {"usb_resets", c.usb_resets},
      {"timestamp_fallbacks", c.timestamp_fallbacks}};
  std::string out;
  for (const auto& [name, value] : fields)
    out += (out.empty() ? "" : " ") + std::string(name) + "=" + std::to_string(value);
  return out;
}

// ---------------------------------------------------------------------------------------------
// Slots: a reference-counted set of buffers handed out as Images.
//
// The camera holds one reference while it uses the set; every Image handed out holds one more.
// Dropping the last reference to an Image marks its slot in `returned_` (an atomic bit mask the
// capture thread collects) and drops the set's reference. The set is destroyed, unmapping the
// kernel buffers and closing the fd they belong to, when the last reference goes: so a device
// can be closed and reopened while consumers still hold frames from it.

class V4l2Camera::Slots {
 public:
  class Slot final : public ImageBuffer {
   public:
    Slot() = default;
    ~Slot() override = default;
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;
    void bind(Slots* owner, int index, std::uint8_t* data, std::size_t size) {
      owner_ = owner;
      index_ = index;
      set_memory(data, size);
    }

   private:
    void release() override { owner_->on_returned(index_); }
    Slots* owner_ = nullptr;
    int index_ = 0;
  };

  /// Kernel buffers of `fd`: the set owns the fd and the mappings from now on.
  static Slots* kernel(V4l2System& sys, int fd) {
    auto* s = new Slots();
    s->sys_ = &sys;
    s->fd_ = fd;
    return s;
  }
  /// `count` heap buffers of `bytes` each.
  static Slots* pool(int count, std::size_t bytes) {
    auto* s = new Slots();
    s->heap_ = std::make_unique<std::uint8_t[]>(bytes * static_cast<std::size_t>(count));
    for (int i = 0; i < count; ++i)
      s->slots_[static_cast<std::size_t>(i)].bind(s, i, s->heap_.get() + bytes * i, bytes);
    s->count_ = count;
    return s;
  }
  /// Adds a mapped kernel buffer (kernel sets only).
  void add_mapping(void* addr, std::size_t length) {
    const auto i = static_cast<std::size_t>(count_);
    maps_[i] = addr;
    lengths_[i] = length;
    slots_[i].bind(this, count_, static_cast<std::uint8_t*>(addr), length);
    ++count_;
  }

  [[nodiscard]] int count() const { return count_; }
  /// Closes the fd now: the kernel frees the queue, while mapped buffers stay valid until
  /// unmapped (vb2 counts the mappings). A new open of the device can then take the queue
  /// even while consumers still hold frames from this one.
  void close_fd() {
    if (fd_ >= 0) sys_->close(fd_);
    fd_ = -1;
  }
  [[nodiscard]] const std::uint8_t* data(int i) const {
    return slots_[static_cast<std::size_t>(i)].data();
  }
  [[nodiscard]] std::uint8_t* mutable_data(int i) {
    return slots_[static_cast<std::size_t>(i)].mutable_data();
  }

  Image hand_out(int i, int width, int height, int stride, PixelFormat format) {
    refs_.fetch_add(1, std::memory_order_relaxed);
    return Image(&slots_[static_cast<std::size_t>(i)], width, height, stride, format);
  }
  /// Slots returned since the last call (capture thread).
  std::uint32_t take_returned() { return returned_.exchange(0, std::memory_order_acquire); }
  void drop() {
    if (refs_.fetch_sub(1, std::memory_order_acq_rel) == 1) delete this;
  }

 private:
  Slots() = default;
  ~Slots() {
    for (int i = 0; i < count_; ++i)
      if (maps_[static_cast<std::size_t>(i)] != nullptr)
        sys_->munmap(maps_[static_cast<std::size_t>(i)], lengths_[static_cast<std::size_t>(i)]);
    if (fd_ >= 0) sys_->close(fd_);
  }
  void on_returned(int i) {
    returned_.fetch_or(1u << static_cast<unsigned>(i), std::memory_order_release);
    drop();
  }

  V4l2System* sys_ = nullptr;
  int fd_ = -1;
  int count_ = 0;
  std::array<Slot, kMaxV4l2Buffers> slots_;
  std::array<void*, kMaxV4l2Buffers> maps_{};
  std::array<std::size_t, kMaxV4l2Buffers> lengths_{};
  std::unique_ptr<std::uint8_t[]> heap_;
  std::atomic<int> refs_{1};  // the creator's
  std::atomic<std::uint32_t> returned_{0};
};

// ---------------------------------------------------------------------------------------------

namespace {

bool is_gone(int err) { return err == ENODEV || err == ENXIO || err == EBADF; }

int bytes_per_pixel(CameraPixelFormat f) { return f == CameraPixelFormat::kYuyv ? 2 : 1; }

// YUYV is Y0 U Y1 V: luma at the even bytes. __restrict lets the compiler vectorise the
// deinterleave (the rows never overlap).
void extract_luma(const std::uint8_t* __restrict yuyv, std::uint8_t* __restrict gray, int width) {
  for (int x = 0; x < width; ++x) gray[x] = yuyv[2 * x];
}

}  // namespace

V4l2Camera::V4l2Camera(V4l2System& sys, V4l2CameraConfig config, int index, UsbResetHook reset)
    : sys_(sys), config_(std::move(config)), index_(index), reset_(std::move(reset)) {}

V4l2Camera::~V4l2Camera() {
  close_device();
  if (pool_ != nullptr) pool_->drop();
}

int V4l2Camera::fd() const { return fd_; }

DurationNs V4l2Camera::period_ns() const {
  const double fps = negotiated_.fps > 0.0 ? negotiated_.fps : config_.fps;
  return fps > 0.0 ? static_cast<DurationNs>(std::llround(1e9 / fps)) : 33 * kNsPerMs;
}

int V4l2Camera::xioctl(unsigned long request, void* arg) {  // NOLINT(google-runtime-int)
  int r = 0;
  while ((r = sys_.ioctl(fd_, request, arg)) < 0 && errno == EINTR) ++counters_.eintr;
  return r;
}

void V4l2Camera::start() {
  if (config_.buffer_count < 2 || config_.buffer_count > kMaxV4l2Buffers)
    throw DeviceError(config_.name + " " + config_.device + ": buffer_count must be 2.." +
                      std::to_string(kMaxV4l2Buffers));
  if (config_.format != CameraPixelFormat::kGrey && pool_ == nullptr) {
    if (config_.pool_size < 1 || config_.pool_size > kMaxV4l2Buffers)
      throw DeviceError(config_.name + " " + config_.device + ": pool_size must be 1..32");
    pool_ = Slots::pool(config_.pool_size,
                        static_cast<std::size_t>(config_.width_px) * config_.height_px);
    free_pool_mask_ = config_.pool_size == 32 ? ~0u : (1u << config_.pool_size) - 1u;
  }
  if (config_.format == CameraPixelFormat::kMjpg && !jpeg_)
    jpeg_ = std::make_unique<recording::JpegDecoder>();
  const char* reason = nullptr;
  std::string message;
  if (open_and_stream(reason, &message) != 0)
    throw DeviceError(config_.name + " " + config_.device + ": " + message);
  state_ = CameraState::kStreaming;
  last_progress_ns_ = sys_.now_ns();
}

void V4l2Camera::stop() {
  close_device();
  state_ = CameraState::kStopped;
}

int V4l2Camera::open_and_stream(const char*& reason, std::string* message) {
  const auto fail = [&](const char* why, int err, const std::string& detail = {}) {
    reason = why;
    if (message != nullptr) {
      *message = why;
      if (!detail.empty()) *message += " " + detail;
      if (err != 0) *message += std::string(": ") + std::strerror(err);
    }
    close_device();
    return err != 0 ? err : EINVAL;
  };

  fd_ = sys_.open(config_.device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int err = errno;
    fd_ = -1;
    return fail("cannot open", err);
  }
  kernel_ = Slots::kernel(sys_, fd_);
  last_sequence_.reset();

  v4l2_capability cap{};
  if (xioctl(VIDIOC_QUERYCAP, &cap) < 0) return fail("VIDIOC_QUERYCAP failed", errno);
  const std::uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0 || (caps & V4L2_CAP_STREAMING) == 0) {
    char hex[32];
    std::snprintf(hex, sizeof hex, "(caps 0x%08x)", caps);
    return fail("not a video capture device with streaming I/O", 0, hex);
  }
  negotiated_.driver.assign(reinterpret_cast<const char*>(cap.driver),
                            strnlen(reinterpret_cast<const char*>(cap.driver), sizeof cap.driver));
  negotiated_.card.assign(reinterpret_cast<const char*>(cap.card),
                          strnlen(reinterpret_cast<const char*>(cap.card), sizeof cap.card));

  // Format: drivers answer S_FMT with the nearest format they support; anything but what we
  // asked for is a refusal.
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<std::uint32_t>(config_.width_px);
  fmt.fmt.pix.height = static_cast<std::uint32_t>(config_.height_px);
  fmt.fmt.pix.pixelformat = fourcc_of(config_.format);
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(VIDIOC_S_FMT, &fmt) < 0) return fail("VIDIOC_S_FMT failed", errno);
  const std::string wanted = std::to_string(config_.width_px) + "x" +
                             std::to_string(config_.height_px) + " " +
                             fourcc_to_string(fourcc_of(config_.format));
  const std::string offered = std::to_string(fmt.fmt.pix.width) + "x" +
                              std::to_string(fmt.fmt.pix.height) + " " +
                              fourcc_to_string(fmt.fmt.pix.pixelformat);
  if (fmt.fmt.pix.pixelformat != fourcc_of(config_.format) ||
      static_cast<int>(fmt.fmt.pix.width) != config_.width_px ||
      static_cast<int>(fmt.fmt.pix.height) != config_.height_px) {
    return fail("refuses", 0, wanted + " (offers " + offered + ")");
  }
  const auto min_stride =
      static_cast<std::uint32_t>(config_.width_px * bytes_per_pixel(config_.format));
  negotiated_.fourcc = fmt.fmt.pix.pixelformat;
  negotiated_.width_px = config_.width_px;
  negotiated_.height_px = config_.height_px;
  negotiated_.stride_bytes = static_cast<int>(config_.format == CameraPixelFormat::kMjpg
                                                  ? 0
                                                  : std::max(fmt.fmt.pix.bytesperline, min_stride));
  negotiated_.size_bytes = fmt.fmt.pix.sizeimage;

  // Frame rate (not every driver can set it; then the requested rate is assumed).
  negotiated_.fps = config_.fps;
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(VIDIOC_G_PARM, &parm) == 0 &&
      (parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0 && config_.fps > 0.0) {
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator =
        static_cast<std::uint32_t>(std::lround(config_.fps * 1000.0));
    if (xioctl(VIDIOC_S_PARM, &parm) == 0 && parm.parm.capture.timeperframe.numerator > 0 &&
        parm.parm.capture.timeperframe.denominator > 0) {
      negotiated_.fps = static_cast<double>(parm.parm.capture.timeperframe.denominator) /
                        parm.parm.capture.timeperframe.numerator;
    }
  }
  // Exposure, for end-of-frame timestamps (units of 100 us).
  v4l2_control ctrl{};
  ctrl.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  negotiated_.exposure_ns =
      xioctl(VIDIOC_G_CTRL, &ctrl) == 0 && ctrl.value > 0 ? DurationNs{ctrl.value} * 100'000 : 0;

  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(config_.buffer_count);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(VIDIOC_REQBUFS, &req) < 0) return fail("VIDIOC_REQBUFS failed", errno);
  if (req.count < 2 || req.count > static_cast<std::uint32_t>(kMaxV4l2Buffers))
    return fail("granted too few or too many buffers", 0, "(" + std::to_string(req.count) + ")");
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    if (xioctl(VIDIOC_QUERYBUF, &buf) < 0) return fail("VIDIOC_QUERYBUF failed", errno);
    void* addr = sys_.mmap(buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                           static_cast<off_t>(buf.m.offset));
    if (addr == MAP_FAILED) return fail("mmap failed", errno);
    kernel_->add_mapping(addr, buf.length);
    // Every buffer must hold a whole frame (MJPEG frames vary; the driver sizes those).
    if (config_.format != CameraPixelFormat::kMjpg &&
        buf.length < static_cast<std::uint32_t>(negotiated_.stride_bytes) *
                         static_cast<std::uint32_t>(negotiated_.height_px))
      return fail("buffers too small for the format", 0);
  }
  negotiated_.buffers = kernel_->count();
  idle_mask_ = negotiated_.buffers == 32 ? ~0u : (1u << negotiated_.buffers) - 1u;
  queued_mask_ = 0;
  out_mask_ = 0;
  if (!stream_on()) return fail("VIDIOC_STREAMON failed", errno);
  return 0;
}

void V4l2Camera::collect_returned() {
  const std::uint32_t back = kernel_->take_returned();
  out_mask_ &= ~back;
  idle_mask_ |= back;
}

int V4l2Camera::queue_idle() {
  for (int i = 0; i < kernel_->count(); ++i) {
    const std::uint32_t bit = 1u << i;
    if ((idle_mask_ & bit) == 0) continue;
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = static_cast<std::uint32_t>(i);
    if (xioctl(VIDIOC_QBUF, &buf) < 0) return errno;
    idle_mask_ &= ~bit;
    queued_mask_ |= bit;
  }
  return 0;
}

bool V4l2Camera::stream_on() {
  collect_returned();
  if (queue_idle() != 0) return false;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(VIDIOC_STREAMON, &type) < 0) return false;
  streaming_ = true;
  last_sequence_.reset();  // vb2 counts from 0 again after STREAMON
  return true;
}

void V4l2Camera::stream_off() {
  if (fd_ < 0 || !streaming_) return;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  (void)xioctl(VIDIOC_STREAMOFF, &type);
  streaming_ = false;
  // STREAMOFF hands every queued buffer back to user space.
  idle_mask_ |= queued_mask_;
  queued_mask_ = 0;
}

void V4l2Camera::close_device() {
  stream_off();
  if (kernel_ != nullptr) {
    kernel_->close_fd();
    kernel_->drop();  // unmaps once consumers have released their frames
    kernel_ = nullptr;
  } else if (fd_ >= 0) {
    sys_.close(fd_);
  }
  fd_ = -1;
  streaming_ = false;
  idle_mask_ = queued_mask_ = out_mask_ = 0;
}

void V4l2Camera::set_state(CameraState s, const char* reason, int err, CameraListener& listener) {
  if (s == state_) return;
  state_ = s;
  listener.on_camera_state(index_, s, reason, err);
}

TimeNs V4l2Camera::step(TimeNs now_ns, short revents, CameraListener& listener) {
  const DurationNs stall_ns = config_.stall_timeout_ns > 0
                                  ? config_.stall_timeout_ns
                                  : std::max<DurationNs>(10 * period_ns(), 500 * kNsPerMs);
  if (state_ == CameraState::kStopped) return now_ns + kNsPerS;

  if (!streaming_) {  // recovering: reopen attempts
    if (now_ns < next_attempt_ns_) return next_attempt_ns_;
    const bool can_reset = reset_ && !config_.usb_id.empty();
    if (reopens_in_row_ >= config_.reopens_before_reset && can_reset && !reset_done_) {
      // Reopening has not brought frames back: reset the port, then give the device time to
      // re-enumerate before the next attempt.
      ++counters_.usb_resets;
      reset_done_ = true;
      (void)reset_(config_.usb_id, config_.device);
      next_attempt_ns_ = now_ns + config_.retry_interval_ns;
      return next_attempt_ns_;
    }
    ++reopens_in_row_;
    close_device();
    const char* reason = nullptr;
    const int err = open_and_stream(reason, nullptr);
    if (err == 0) {
      ++counters_.reopens;
      last_progress_ns_ = now_ns;
      return now_ns + stall_ns;
    }
    ++counters_.reopen_failures;
    if (reopens_in_row_ > config_.reopens_before_reset && (reset_done_ || !can_reset))
      set_state(CameraState::kDead, reason, err, listener);
    next_attempt_ns_ = now_ns + config_.retry_interval_ns;
    return next_attempt_ns_;
  }

  collect_returned();
  if (queue_idle() != 0) {
    const int err = errno;
    if (is_gone(err)) return recover(now_ns, Rung::kReopen, "device gone", err, listener);
    if (err == EIO) ++counters_.io_errors;
  }
  if ((revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
    // vb2 signals POLLERR for a queue in error (an I/O error: restart the stream); uvcvideo
    // hangs up on unplug (gone: reopen, counted as a disconnect).
    const bool queue_error = (revents & POLLERR) != 0 && (revents & (POLLHUP | POLLNVAL)) == 0;
    if (queue_error) {
      ++counters_.io_errors;
      return recover(now_ns, Rung::kRestart, "queue in error (POLLERR)", EIO, listener);
    }
    return recover(now_ns, Rung::kReopen, "device gone (POLLHUP)", ENODEV, listener);
  }
  if ((revents & POLLIN) != 0) {
    const int err = dequeue_all(now_ns, listener);
    if (err == EIO) return recover(now_ns, Rung::kRestart, "I/O error", EIO, listener);
    if (err != 0) return recover(now_ns, Rung::kReopen, "device gone", err, listener);
  }
  if (now_ns - last_progress_ns_ >= stall_ns) {
    ++counters_.timeouts;
    return recover(
        now_ns, restarts_in_row_ < config_.restarts_before_reopen ? Rung::kRestart : Rung::kReopen,
        "no frame within the stall timeout", ETIMEDOUT, listener);
  }
  return last_progress_ns_ + stall_ns;
}

TimeNs V4l2Camera::recover(TimeNs now_ns, Rung rung, const char* reason, int err,
                           CameraListener& listener) {
  if (err == ENODEV || is_gone(err)) ++counters_.disconnects;
  set_state(CameraState::kRecovering, reason, err, listener);
  last_progress_ns_ = now_ns;
  if (rung == Rung::kRestart && restarts_in_row_ < config_.restarts_before_reopen) {
    ++restarts_in_row_;
    ++counters_.stream_restarts;
    stream_off();
    if (stream_on()) return now_ns + 1;  // check the stall clock from now
  }
  // Reopen: close now (buffers held by consumers stay mapped), first attempt at once.
  close_device();
  restarts_in_row_ = 0;
  next_attempt_ns_ = now_ns;
  return now_ns;
}

int V4l2Camera::dequeue_all(TimeNs now_ns, CameraListener& listener) {
  for (int n = 0; n < kernel_->count(); ++n) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (xioctl(VIDIOC_DQBUF, &buf) < 0) {
      const int err = errno;
      if (err == EAGAIN) {
        if (n == 0) ++counters_.eagain;
        return 0;
      }
      if (err == EIO) ++counters_.io_errors;
      return err;
    }
    if (buf.index >= static_cast<std::uint32_t>(kernel_->count())) {
      ++counters_.corrupt;
      continue;
    }
    const std::uint32_t bit = 1u << buf.index;
    queued_mask_ &= ~bit;
    idle_mask_ |= bit;  // deliver() moves it to out_mask_ when a consumer gets it
    deliver(buf, now_ns, listener);
  }
  return 0;
}

void V4l2Camera::deliver(const v4l2_buffer& buf, TimeNs now_ns, CameraListener& listener) {
  const int index = static_cast<int>(buf.index);
  if ((buf.flags & V4L2_BUF_FLAG_ERROR) != 0 || buf.bytesused == 0) {
    ++counters_.corrupt;
    return;
  }
  const int w = negotiated_.width_px;
  const int h = negotiated_.height_px;
  const int stride = negotiated_.stride_bytes;
  if (config_.format != CameraPixelFormat::kMjpg &&
      buf.bytesused < static_cast<std::uint32_t>(stride) * static_cast<std::uint32_t>(h)) {
    ++counters_.corrupt;
    return;
  }

  // Time: the kernel's monotonic stamp (start of exposure, or end of frame minus exposure).
  TimeNs t_ns = 0;
  if ((buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
    t_ns = static_cast<TimeNs>(buf.timestamp.tv_sec) * kNsPerS +
           static_cast<TimeNs>(buf.timestamp.tv_usec) * 1000;
    negotiated_.start_of_exposure =
        (buf.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
    if (!negotiated_.start_of_exposure) t_ns -= negotiated_.exposure_ns;
  } else {
    t_ns = now_ns - period_ns();
    ++counters_.timestamp_fallbacks;
  }

  // Sequence: gaps are frames the device dropped (no buffer was queued, or the bus lost them).
  if (last_sequence_) {
    if (buf.sequence > *last_sequence_ + 1) {
      counters_.dropped += buf.sequence - *last_sequence_ - 1;
    } else if (buf.sequence <= *last_sequence_) {
      ++counters_.sequence_errors;
    }
  }
  last_sequence_ = buf.sequence;
  if (t_ns <= last_t_ns_) {
    ++counters_.non_monotonic;
    return;
  }

  CameraFrame frame;
  frame.t_ns = t_ns;
  frame.publish_t_ns = now_ns;
  frame.sequence = buf.sequence;
  if (config_.format == CameraPixelFormat::kGrey) {
    frame.image = kernel_->hand_out(index, w, h, stride, PixelFormat::kGray8);
    idle_mask_ &= ~(1u << index);
    out_mask_ |= 1u << index;
  } else {
    free_pool_mask_ |= pool_->take_returned();
    if (free_pool_mask_ == 0) {
      ++counters_.pool_exhausted;
      return;
    }
    const int slot = __builtin_ctz(free_pool_mask_);
    std::uint8_t* dst = pool_->mutable_data(slot);
    const std::uint8_t* src = kernel_->data(index);
    if (config_.format == CameraPixelFormat::kYuyv) {
      for (int y = 0; y < h; ++y)
        extract_luma(src + static_cast<std::ptrdiff_t>(y) * stride,
                     dst + static_cast<std::ptrdiff_t>(y) * w, w);
    } else if (!jpeg_->decode_gray({src, buf.bytesused}, {w, h}, dst, w, decode_error_)) {
      ++counters_.corrupt;
      return;
    }
    free_pool_mask_ &= ~(1u << slot);
    frame.image = pool_->hand_out(slot, w, h, w, PixelFormat::kGray8);
  }
  last_t_ns_ = t_ns;
  last_progress_ns_ = now_ns;
  restarts_in_row_ = 0;
  reopens_in_row_ = 0;
  reset_done_ = false;
  ++counters_.frames;
  if (state_ != CameraState::kStreaming)
    set_state(CameraState::kStreaming, "delivering frames", 0, listener);
  listener.on_frame(index_, std::move(frame));
}

}  // namespace wallar::drivers
