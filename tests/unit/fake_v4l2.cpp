// SPDX-License-Identifier: Apache-2.0
/// @file fake_v4l2.cpp
/// @brief The fake V4L2 device; see fake_v4l2.hpp.
#include "fake_v4l2.hpp"

#include <sys/mman.h>

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstring>

#include "wallar/drivers/recording/jpeg.hpp"

namespace wallar::test {
namespace {

constexpr int kFirstFd = 1000;
constexpr std::uint32_t kPage = 4096;

int bytes_per_pixel(std::uint32_t fourcc) { return fourcc == V4L2_PIX_FMT_YUYV ? 2 : 1; }

int fail(int err) {
  errno = err;
  return -1;
}

struct BufInfo {
  std::uint32_t bytesused = 0;
  std::uint32_t flags = 0;
  std::uint32_t sequence = 0;
  TimeNs t_ns = 0;
  bool queued = false;
};

}  // namespace

struct FakeV4l2Device::Queue {
  std::vector<std::vector<std::uint8_t>> memory;
  std::array<BufInfo, 32> info{};
};

FakeV4l2Device::FakeV4l2Device(FakeV4l2& sys, std::string path, FakeCameraSpec spec)
    : sys_(sys), path_(std::move(path)), spec_(std::move(spec)), fps_(spec_.fps) {}

void FakeV4l2Device::fail_next(unsigned long request, int err, int count) {  // NOLINT
  fail_request_ = request;
  fail_errno_ = err;
  fail_left_ = count;
}

void FakeV4l2Device::unplug() {
  present_ = false;
  streaming_ = false;
  owner_fd_ = -1;
  queued_count_ = done_count_ = 0;
  queue_.reset();  // replugged, it is a new device; mappings keep the old memory alive
  buffer_count_ = 0;
}

const std::uint8_t* FakeV4l2Device::buffer_memory(int index) const {
  return queue_ ? queue_->memory[static_cast<std::size_t>(index)].data() : nullptr;
}

void FakeV4l2Device::on_close(int fd) {
  if (fd != owner_fd_) return;
  streaming_ = false;
  owner_fd_ = -1;
  queued_count_ = done_count_ = 0;
  queue_.reset();  // mappings keep the memory alive
  buffer_count_ = 0;
}

short FakeV4l2Device::revents() const {
  if (!present_) return POLLERR | POLLHUP;
  if (!streaming_ || queue_error_) return POLLERR;
  return done_count_ > 0 ? POLLIN : 0;
}

TimeNs FakeV4l2Device::next_frame_ns() const {
  if (!present_ || !streaming_ || spec_.triggered) return INT64_MAX;
  return next_frame_ns_;
}

void FakeV4l2Device::produce(TimeNs t_ns) {
  if (!present_ || !streaming_ || stalled_ || stall_until_streamon_) return;
  if (queued_count_ == 0) {  // no buffer to fill: the frame is lost, its number skipped
    ++lost_;
    ++sequence_;
    return;
  }
  const int index = queued_[static_cast<std::size_t>(queued_head_)];
  queued_head_ = (queued_head_ + 1) % 32;
  --queued_count_;
  BufInfo& info = queue_->info[static_cast<std::size_t>(index)];
  std::vector<std::uint8_t>& mem = queue_->memory[static_cast<std::size_t>(index)];
  const int w = spec_.width_px, h = spec_.height_px;
  const bool render =
      spec_.render_every_frame || produced_ < static_cast<std::uint64_t>(buffer_count_);
  if (fourcc_ == V4L2_PIX_FMT_MJPEG && !render && !first_jpeg_.empty()) {
    std::memcpy(mem.data(), first_jpeg_.data(), std::min(first_jpeg_.size(), mem.size()));
    info.bytesused = static_cast<std::uint32_t>(std::min(first_jpeg_.size(), mem.size()));
  } else if (fourcc_ == V4L2_PIX_FMT_MJPEG) {
    Image gray = Image::allocate(w, h, PixelFormat::kGray8);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) gray.mutable_data()[y * w + x] = pattern(produced_, x, y);
    std::vector<std::uint8_t> jpeg = recording::encode_jpeg_gray(gray, 95, true);
    if (!spec_.render_every_frame && first_jpeg_.empty()) first_jpeg_ = jpeg;
    if (corrupt_jpeg_next_) {
      jpeg.resize(jpeg.size() / 2);
      corrupt_jpeg_next_ = false;
    }
    std::memcpy(mem.data(), jpeg.data(), std::min(jpeg.size(), mem.size()));
    info.bytesused = static_cast<std::uint32_t>(std::min(jpeg.size(), mem.size()));
  } else {
    const int bpp = bytes_per_pixel(fourcc_);
    for (int y = 0; render && y < h; ++y) {
      std::uint8_t* row = mem.data() + static_cast<std::ptrdiff_t>(y) * w * bpp;
      for (int x = 0; x < w; ++x) {
        row[x * bpp] = pattern(produced_, x, y);
        if (bpp == 2) row[x * bpp + 1] = 128;  // U or V
      }
    }
    info.bytesused = static_cast<std::uint32_t>(w * h * bpp);
  }
  if (short_next_) {
    info.bytesused /= 2;
    short_next_ = false;
  }
  info.flags = spec_.timestamp_flags;
  if (error_next_) {
    info.flags |= V4L2_BUF_FLAG_ERROR;
    error_next_ = false;
  }
  info.sequence = sequence_++;
  info.t_ns = repeat_timestamp_ ? last_stamp_ns_ : t_ns;
  repeat_timestamp_ = false;
  last_stamp_ns_ = info.t_ns;
  info.queued = false;
  done_[static_cast<std::size_t>((done_head_ + done_count_) % 32)] = index;
  ++done_count_;
  ++produced_;
}

int FakeV4l2Device::ioctl(int fd, unsigned long request, void* arg) {  // NOLINT
  if (!present_) return fail(ENODEV);
  if (fail_left_ > 0 && request == fail_request_) {
    --fail_left_;
    return fail(fail_errno_);
  }
  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto* cap = static_cast<v4l2_capability*>(arg);
      std::memset(cap, 0, sizeof *cap);
      std::strncpy(reinterpret_cast<char*>(cap->driver), "fake", sizeof cap->driver - 1);
      std::strncpy(reinterpret_cast<char*>(cap->card), "wallar fake camera", sizeof cap->card - 1);
      cap->capabilities = spec_.caps | V4L2_CAP_DEVICE_CAPS;
      cap->device_caps = spec_.caps;
      return 0;
    }
    // What it offers: each format at the spec's one size, at the spec's rate and half of it.
    case VIDIOC_ENUM_FMT: {
      auto* desc = static_cast<v4l2_fmtdesc*>(arg);
      if (desc->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || desc->index >= spec_.fourccs.size())
        return fail(EINVAL);
      desc->pixelformat = spec_.fourccs[desc->index];
      return 0;
    }
    case VIDIOC_ENUM_FRAMESIZES: {
      auto* size = static_cast<v4l2_frmsizeenum*>(arg);
      if (size->index != 0) return fail(EINVAL);
      size->type = V4L2_FRMSIZE_TYPE_DISCRETE;
      size->discrete.width = static_cast<std::uint32_t>(spec_.width_px);
      size->discrete.height = static_cast<std::uint32_t>(spec_.height_px);
      return 0;
    }
    case VIDIOC_ENUM_FRAMEINTERVALS: {
      auto* iv = static_cast<v4l2_frmivalenum*>(arg);
      if (iv->index > 1 || iv->width != static_cast<std::uint32_t>(spec_.width_px) ||
          iv->height != static_cast<std::uint32_t>(spec_.height_px))
        return fail(EINVAL);
      iv->type = V4L2_FRMIVAL_TYPE_DISCRETE;
      iv->discrete.numerator = 1000 * (iv->index + 1);
      iv->discrete.denominator = static_cast<std::uint32_t>(std::lround(spec_.fps * 1000.0));
      return 0;
    }
    case VIDIOC_S_FMT: {
      if (streaming_ || buffer_count_ > 0) return fail(EBUSY);
      auto* fmt = static_cast<v4l2_format*>(arg);
      if (fmt->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      std::uint32_t chosen = spec_.fourccs.front();
      for (std::uint32_t f : spec_.fourccs)
        if (f == fmt->fmt.pix.pixelformat) chosen = f;
      fourcc_ = chosen;
      fmt->fmt.pix.pixelformat = chosen;
      fmt->fmt.pix.width = static_cast<std::uint32_t>(spec_.width_px);
      fmt->fmt.pix.height = static_cast<std::uint32_t>(spec_.height_px);
      fmt->fmt.pix.field = V4L2_FIELD_NONE;
      fmt->fmt.pix.bytesperline =
          chosen == V4L2_PIX_FMT_MJPEG
              ? 0
              : static_cast<std::uint32_t>(spec_.width_px * bytes_per_pixel(chosen));
      fmt->fmt.pix.sizeimage =
          static_cast<std::uint32_t>(spec_.width_px * spec_.height_px * bytes_per_pixel(chosen));
      if (chosen == V4L2_PIX_FMT_MJPEG) fmt->fmt.pix.sizeimage *= 2;
      return 0;
    }
    case VIDIOC_G_PARM:
    case VIDIOC_S_PARM: {
      auto* parm = static_cast<v4l2_streamparm*>(arg);
      if (request == VIDIOC_S_PARM) {
        if (!spec_.can_set_fps) return fail(EINVAL);
        const v4l2_fract f = parm->parm.capture.timeperframe;
        if (f.numerator > 0 && f.denominator > 0)
          fps_ = static_cast<double>(f.denominator) / f.numerator;
      }
      parm->parm.capture.capability = spec_.can_set_fps ? V4L2_CAP_TIMEPERFRAME : 0;
      parm->parm.capture.timeperframe.numerator = 1000;
      parm->parm.capture.timeperframe.denominator =
          static_cast<std::uint32_t>(std::lround(fps_ * 1000.0));
      return 0;
    }
    case VIDIOC_G_CTRL: {
      auto* ctrl = static_cast<v4l2_control*>(arg);
      if (ctrl->id != V4L2_CID_EXPOSURE_ABSOLUTE || spec_.exposure_100us <= 0) return fail(EINVAL);
      ctrl->value = spec_.exposure_100us;
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto* req = static_cast<v4l2_requestbuffers*>(arg);
      if (streaming_) return fail(EBUSY);
      if (req->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
      const int count = std::min(static_cast<int>(req->count), spec_.max_buffers);
      queue_ = std::make_shared<Queue>();
      const std::size_t length =
          static_cast<std::size_t>(spec_.width_px) * spec_.height_px * 2;  // fits every format
      queue_->memory.assign(static_cast<std::size_t>(count), std::vector<std::uint8_t>(length));
      buffer_count_ = count;
      owner_fd_ = count > 0 ? fd : -1;
      queued_count_ = done_count_ = 0;
      req->count = static_cast<std::uint32_t>(count);
      return 0;
    }
    case VIDIOC_QUERYBUF:
    case VIDIOC_QBUF:
    case VIDIOC_DQBUF: {
      auto* buf = static_cast<v4l2_buffer*>(arg);
      if (fd != owner_fd_) return fail(EBUSY);
      if (buf->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buf->memory != V4L2_MEMORY_MMAP)
        return fail(EINVAL);
      if (request == VIDIOC_DQBUF) {
        if (!streaming_) return fail(EINVAL);
        if (queue_error_) return fail(EIO);
        if (done_count_ == 0) return fail(EAGAIN);
        if (eagain_left_ > 0) {
          --eagain_left_;
          return fail(EAGAIN);
        }
        const int index = done_[static_cast<std::size_t>(done_head_)];
        done_head_ = (done_head_ + 1) % 32;
        --done_count_;
        const BufInfo& info = queue_->info[static_cast<std::size_t>(index)];
        buf->index = static_cast<std::uint32_t>(index);
        buf->bytesused = info.bytesused;
        buf->flags = info.flags;
        buf->sequence = info.sequence;
        buf->timestamp.tv_sec = info.t_ns / kNsPerS;
        buf->timestamp.tv_usec = (info.t_ns % kNsPerS) / 1000;
        buf->length = static_cast<std::uint32_t>(queue_->memory[0].size());
        return 0;
      }
      if (buf->index >= static_cast<std::uint32_t>(buffer_count_)) return fail(EINVAL);
      BufInfo& info = queue_->info[buf->index];
      if (request == VIDIOC_QUERYBUF) {
        buf->length = static_cast<std::uint32_t>(queue_->memory[buf->index].size());
        buf->m.offset = buf->index * kPage;
        buf->flags = info.queued ? V4L2_BUF_FLAG_QUEUED : 0;
        return 0;
      }
      if (info.queued) return fail(EINVAL);  // QBUF of a queued buffer
      info.queued = true;
      queued_[static_cast<std::size_t>((queued_head_ + queued_count_) % 32)] =
          static_cast<int>(buf->index);
      ++queued_count_;
      return 0;
    }
    case VIDIOC_STREAMON:
      if (fd != owner_fd_) return fail(EBUSY);
      if (!streaming_) {
        streaming_ = true;
        ++streamons_;
        stall_until_streamon_ = false;
        sequence_ = 0;
        next_frame_ns_ = sys_.now_ns() + static_cast<DurationNs>(1e9 / fps_) + spec_.phase_ns;
      }
      return 0;
    case VIDIOC_STREAMOFF:
      if (fd != owner_fd_) return fail(EBUSY);
      streaming_ = false;
      queue_error_ = false;
      for (auto& info : queue_->info) info.queued = false;
      queued_count_ = done_count_ = 0;
      return 0;
    default:
      return fail(ENOTTY);
  }
}

// ---------------------------------------------------------------------------------------------

FakeV4l2::FakeV4l2() = default;
FakeV4l2::~FakeV4l2() = default;

FakeV4l2Device& FakeV4l2::add_device(const std::string& path, FakeCameraSpec spec) {
  devices_.push_back(std::make_unique<FakeV4l2Device>(*this, path, std::move(spec)));
  return *devices_.back();
}

void FakeV4l2::trigger() {
  for (auto& d : devices_)
    if (d->spec_.triggered) d->produce(now_ns_ + d->spec_.phase_ns);
}

FakeV4l2Device* FakeV4l2::device_of(int fd) {
  std::lock_guard lock(mutex_);
  const int i = fd - kFirstFd;
  if (i < 0 || i >= static_cast<int>(fds_.size())) return nullptr;
  return fds_[static_cast<std::size_t>(i)];
}

int FakeV4l2::open_fds() const {
  std::lock_guard lock(mutex_);
  int n = 0;
  for (auto* d : fds_) n += d != nullptr ? 1 : 0;
  return n;
}

int FakeV4l2::mappings() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(mappings_.size());
}

int FakeV4l2::open(const char* path, int /*flags*/) {
  for (auto& d : devices_) {
    if (d->path_ != path) continue;
    if (!d->present_) return fail(ENOENT);
    std::lock_guard lock(mutex_);
    for (std::size_t i = 0; i < fds_.size(); ++i) {
      if (fds_[i] != nullptr) continue;
      fds_[i] = d.get();
      ++d->opens_;
      return kFirstFd + static_cast<int>(i);
    }
    return fail(EMFILE);
  }
  return fail(ENOENT);
}

int FakeV4l2::close(int fd) {
  FakeV4l2Device* d = device_of(fd);
  if (d == nullptr) return fail(EBADF);
  d->on_close(fd);
  std::lock_guard lock(mutex_);
  fds_[static_cast<std::size_t>(fd - kFirstFd)] = nullptr;
  return 0;
}

int FakeV4l2::ioctl(int fd, unsigned long request, void* arg) {  // NOLINT
  if (eintr_ioctls_ > 0) {
    --eintr_ioctls_;
    return fail(EINTR);
  }
  FakeV4l2Device* d = device_of(fd);
  if (d == nullptr) return fail(EBADF);
  return d->ioctl(fd, request, arg);
}

void* FakeV4l2::mmap(std::size_t length, int /*prot*/, int /*flags*/, int fd, off_t offset) {
  FakeV4l2Device* d = device_of(fd);
  if (d == nullptr) {
    errno = EBADF;
    return MAP_FAILED;
  }
  if (!d->present_ || !d->queue_ || fd != d->owner_fd_) {
    errno = d->present_ ? EINVAL : ENODEV;
    return MAP_FAILED;
  }
  const auto index = static_cast<std::size_t>(offset / kPage);
  if (index >= d->queue_->memory.size() || length > d->queue_->memory[index].size()) {
    errno = EINVAL;
    return MAP_FAILED;
  }
  void* addr = d->queue_->memory[index].data();
  std::lock_guard lock(mutex_);
  mappings_[addr] = std::shared_ptr<void>(d->queue_, addr);
  return addr;
}

int FakeV4l2::munmap(void* addr, std::size_t /*length*/) {
  std::shared_ptr<void> keep;  // freed outside the lock
  std::lock_guard lock(mutex_);
  auto it = mappings_.find(addr);
  if (it == mappings_.end()) return fail(EINVAL);
  keep = std::move(it->second);
  mappings_.erase(it);
  return 0;
}

int FakeV4l2::poll(pollfd* fds, nfds_t count, int timeout_ms) {
  if (eintr_polls_ > 0) {
    --eintr_polls_;
    return fail(EINTR);
  }
  const TimeNs deadline =
      timeout_ms < 0 ? INT64_MAX / 2 : now_ns_ + static_cast<TimeNs>(timeout_ms) * kNsPerMs;
  for (;;) {
    int ready = 0;
    for (nfds_t i = 0; i < count; ++i) {
      FakeV4l2Device* d = device_of(fds[i].fd);
      fds[i].revents = d == nullptr ? POLLNVAL : d->revents();
      if (fds[i].revents != 0) ++ready;
    }
    if (ready > 0) return ready;
    TimeNs next = INT64_MAX;
    for (auto& d : devices_) next = std::min(next, d->next_frame_ns());
    if (next > deadline) {
      now_ns_ = std::max(now_ns_, deadline);
      return 0;
    }
    now_ns_ = std::max(now_ns_, next);
    for (auto& d : devices_) {
      if (d->next_frame_ns() <= now_ns_) {
        d->produce(d->next_frame_ns_);
        d->next_frame_ns_ += static_cast<DurationNs>(1e9 / d->fps_);
      }
    }
  }
}

}  // namespace wallar::test
