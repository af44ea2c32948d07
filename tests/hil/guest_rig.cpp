// SPDX-License-Identifier: Apache-2.0
/// @file guest_rig.cpp
/// @brief The guest side of the hardware-in-the-loop boot test (tools/boot-test --hil): makes
/// two vivid instances the headset's stereo cameras, playing a recording into them, and a
/// uinput keyboard its remote. Never part of the image: tools/boot-test adds it to a copy.
///
///   wallar_hil_rig play RECORDING [--cams 0,2] [--outs 1,3] [--keys NAME]
///   wallar_hil_rig ctrl /dev/videoN ID VALUE
///   wallar_hil_rig match RECORDING CAPTURED
///
/// play: for each side, the vivid capture node (/dev/video{0,2}) gets HDMI DV timings of
/// 1024x768 at exactly 20 Hz (CVT reduced blanking v2; vivid's capture accepts only standard
/// or CVT/GTF timings), its video loop on, its OSD text off and start-of-exposure timestamps;
/// the output node (/dev/video{1,3}) the same timings and the recording's 752x480 GREY
/// composed at (0,0), which the capture (crop mode) returns as a 752x480 GREY frame: vivid
/// copies the output buffer on screen into each capture buffer (loop_video). The outputs are
/// paced by vivid's own 20 Hz output thread (the recording's rate, checked), one buffer back
/// per tick; the player refills left and right with frame i together, so a pair's two images
/// are the same recorded pair unless the two instances' ticks straddle a jiffy. Forth and back
/// over the recording until SIGTERM. When an instance is disconnected (vivid's "disconnect"
/// control: every ioctl answers ENODEV) the player closes it, which lets vivid reconnect once
/// the product has closed it too, and reopens it; each reconnect is counted.
/// --keys NAME creates a uinput keyboard named NAME (keys R and Q); SIGUSR1 presses R once.
/// Ready (sd_notify READY=1, for a Type=notify unit) once both outputs stream. SIGUSR2 or
/// exit prints one line of counters.
///
/// ctrl: sets one V4L2 control (vivid's error injection) and closes the node at once.
/// match: which recorded pair each pair of a recording made through the cameras carries
/// (`wallar record` on the HIL board), and whether its images are bit-identical.
///
/// Threading: one thread; signals only set flags.
#include <fcntl.h>
#include <linux/uinput.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "wallar/core/image.hpp"
#include "wallar/core/time.hpp"
#include "wallar/drivers/recording/euroc.hpp"

namespace {

using namespace wallar;

// vivid's controls (drivers/media/test-drivers/vivid/vivid-ctrls.c): VIVID_CID_VIVID_BASE
// (0x00f00000 | 0xf000) + n.
constexpr std::uint32_t kVividBase = 0x00f0f000;
constexpr std::uint32_t kCidOsdTextMode = kVividBase + 1;
constexpr std::uint32_t kCidTimestampSource = kVividBase + 24;
constexpr std::uint32_t kCidLoopVideo = kVividBase + 37;

constexpr int kWidth = 752;
constexpr int kHeight = 480;
constexpr int kBuffers = 4;
constexpr DurationNs kFramePeriodNs = 50 * kNsPerMs;

std::atomic<bool> g_stop{false};
std::atomic<bool> g_press{false};
std::atomic<bool> g_report{false};

void on_stop(int /*signo*/) { g_stop.store(true); }
void on_press(int /*signo*/) { g_press.store(true); }
void on_report(int /*signo*/) { g_report.store(true); }

[[noreturn]] void fail(const std::string& what) { throw std::runtime_error(what); }

int xioctl(int fd, unsigned long request, void* arg) {  // NOLINT(google-runtime-int)
  int r = 0;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

std::string err(const std::string& what) { return what + ": " + std::strerror(errno); }

/// 1024x768 progressive at 20 Hz: htotal 1104, vtotal 783, 17.28864 MHz (CVT-RBv2 blanking:
/// vsync 8, positive hsync only). The capture stores its own recomputed CVT timings; both
/// sides give a frame period of exactly 1/20 s.
v4l2_dv_timings timings_20hz(std::uint64_t pixelclock) {
  v4l2_dv_timings t{};
  t.type = V4L2_DV_BT_656_1120;
  v4l2_bt_timings& bt = t.bt;
  bt.width = 1024;
  bt.height = 768;
  bt.interlaced = 0;
  bt.polarities = V4L2_DV_HSYNC_POS_POL;
  bt.pixelclock = pixelclock;
  bt.hfrontporch = 8;
  bt.hsync = 32;
  bt.hbackporch = 40;
  bt.vfrontporch = 1;
  bt.vsync = 8;
  bt.vbackporch = 6;
  bt.standards = V4L2_DV_BT_STD_CVT;
  return t;
}

void set_ctrl(int fd, std::uint32_t id, std::int32_t value, const std::string& where) {
  v4l2_control c{};
  c.id = id;
  c.value = value;
  if (xioctl(fd, VIDIOC_S_CTRL, &c) < 0) {
    fail(err(where + ": VIDIOC_S_CTRL 0x" + [&] {
      char b[16];
      std::snprintf(b, sizeof b, "%x", id);
      return std::string(b);
    }()));
  }
}

/// The capture node's part of the loop: timings, loop on, no OSD, start-of-exposure stamps.
void configure_capture(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) fail(err(path));
  v4l2_input input{};
  input.index = 0;
  xioctl(fd, VIDIOC_S_INPUT, &input.index);
  v4l2_dv_timings t = timings_20hz(17'288'640);
  if (xioctl(fd, VIDIOC_S_DV_TIMINGS, &t) < 0) {
    const std::string e = err(path + ": VIDIOC_S_DV_TIMINGS 1024x768@20");
    ::close(fd);
    fail(e);
  }
  set_ctrl(fd, kCidLoopVideo, 1, path);
  set_ctrl(fd, kCidOsdTextMode, 2, path);      // "None"
  set_ctrl(fd, kCidTimestampSource, 1, path);  // start of exposure
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  xioctl(fd, VIDIOC_G_PARM, &parm);
  const auto& tpf = parm.parm.capture.timeperframe;
  std::printf("hil-rig: %s: 1024x768 HDMI timings, %u/%u s per frame, loop on\n", path.c_str(),
              tpf.numerator, tpf.denominator);
  ::close(fd);
}

/// One vivid output node streaming the recording.
class Output {
 public:
  explicit Output(std::string path) : path_(std::move(path)) {}
  ~Output() { close(); }
  Output(const Output&) = delete;
  Output& operator=(const Output&) = delete;

  [[nodiscard]] bool open() {
    fd_ = ::open(path_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) return false;
    v4l2_output output{};
    output.index = 0;
    xioctl(fd_, VIDIOC_S_OUTPUT, &output.index);
    v4l2_dv_timings t = timings_20hz(17'288'000);
    if (xioctl(fd_, VIDIOC_S_DV_TIMINGS, &t) < 0) fail(err(path_ + ": VIDIOC_S_DV_TIMINGS"));
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    fmt.fmt.pix.width = kWidth;
    fmt.fmt.pix.height = kHeight;
    fmt.fmt.pix.pixelformat = V4L2_PIX_FMT_GREY;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (xioctl(fd_, VIDIOC_S_FMT, &fmt) < 0) fail(err(path_ + ": VIDIOC_S_FMT GREY 752x480"));
    if (fmt.fmt.pix.width != kWidth || fmt.fmt.pix.height != kHeight ||
        fmt.fmt.pix.pixelformat != V4L2_PIX_FMT_GREY) {
      fail(path_ + ": the output gave " + std::to_string(fmt.fmt.pix.width) + "x" +
           std::to_string(fmt.fmt.pix.height) + ", not 752x480 GREY");
    }
    stride_ = static_cast<int>(fmt.fmt.pix.bytesperline);
    v4l2_requestbuffers req{};
    req.count = kBuffers;
    req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    req.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_REQBUFS, &req) < 0 || req.count < 3) fail(err(path_ + ": REQBUFS"));
    maps_.clear();
    for (std::uint32_t i = 0; i < req.count; ++i) {
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
      b.memory = V4L2_MEMORY_MMAP;
      b.index = i;
      if (xioctl(fd_, VIDIOC_QUERYBUF, &b) < 0) fail(err(path_ + ": QUERYBUF"));
      void* p = ::mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, b.m.offset);
      if (p == MAP_FAILED) fail(err(path_ + ": mmap"));
      maps_.push_back({static_cast<std::uint8_t*>(p), b.length});
    }
    return true;
  }

  void close() {
    for (const auto& m : maps_) ::munmap(m.data, m.length);
    maps_.clear();
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  /// Fills buffer `index` with `image` and queues it; false when the device went away.
  bool queue(std::uint32_t index, const Image& image) {
    std::uint8_t* dst = maps_[index].data;
    for (int y = 0; y < kHeight; ++y) {
      std::memcpy(dst + static_cast<std::ptrdiff_t>(y) * stride_, image.row(y), kWidth);
    }
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = index;
    b.bytesused = static_cast<std::uint32_t>(stride_ * kHeight);
    b.field = V4L2_FIELD_NONE;
    if (xioctl(fd_, VIDIOC_QBUF, &b) < 0) return false;
    ++queued;
    return true;
  }
  bool stream_on() {
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    return xioctl(fd_, VIDIOC_STREAMON, &type) == 0;
  }
  /// A buffer vivid has finished showing, or -1 (none yet: EAGAIN; gone: lost set).
  int dequeue() {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    b.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_DQBUF, &b) < 0) {
      if (errno != EAGAIN) lost = true;
      return -1;
    }
    return static_cast<int>(b.index);
  }

  [[nodiscard]] int fd() const { return fd_; }
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] std::size_t buffers() const { return maps_.size(); }

  std::uint64_t queued = 0;
  bool lost = false;

 private:
  struct Map {
    std::uint8_t* data;
    std::size_t length;
  };
  std::string path_;
  int fd_ = -1;
  int stride_ = kWidth;
  std::vector<Map> maps_;
};

/// A uinput keyboard with R (reset) and Q (exit).
class Keyboard {
 public:
  explicit Keyboard(const std::string& name) {
    fd_ = ::open("/dev/uinput", O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) fail(err("/dev/uinput"));
    xioctl(fd_, UI_SET_EVBIT, reinterpret_cast<void*>(EV_KEY));  // NOLINT
    xioctl(fd_, UI_SET_KEYBIT, reinterpret_cast<void*>(KEY_R));  // NOLINT
    xioctl(fd_, UI_SET_KEYBIT, reinterpret_cast<void*>(KEY_Q));  // NOLINT
    uinput_setup setup{};
    setup.id.bustype = BUS_VIRTUAL;
    setup.id.vendor = 0x1d6b;
    setup.id.product = 0x0104;
    std::snprintf(setup.name, UINPUT_MAX_NAME_SIZE, "%s", name.c_str());
    if (xioctl(fd_, UI_DEV_SETUP, &setup) < 0 || xioctl(fd_, UI_DEV_CREATE, nullptr) < 0) {
      fail(err("/dev/uinput: " + name));
    }
  }
  ~Keyboard() {
    xioctl(fd_, UI_DEV_DESTROY, nullptr);
    ::close(fd_);
  }
  Keyboard(const Keyboard&) = delete;
  Keyboard& operator=(const Keyboard&) = delete;

  void press(int code) {
    emit(EV_KEY, code, 1);
    emit(EV_SYN, SYN_REPORT, 0);
    emit(EV_KEY, code, 0);
    emit(EV_SYN, SYN_REPORT, 0);
    ++presses;
  }
  std::uint64_t presses = 0;

 private:
  void emit(int type, int code, int value) {
    input_event ev{};
    ev.type = static_cast<std::uint16_t>(type);
    ev.code = static_cast<std::uint16_t>(code);
    ev.value = value;
    if (::write(fd_, &ev, sizeof ev) != static_cast<ssize_t>(sizeof ev)) {
      std::fprintf(stderr, "hil-rig: uinput write: %s\n", std::strerror(errno));
    }
  }
  int fd_ = -1;
};

std::vector<int> parse_pair(std::string_view text) {
  const std::size_t comma = text.find(',');
  if (comma == std::string_view::npos) fail("expected N,M, got '" + std::string(text) + "'");
  return {std::atoi(std::string(text.substr(0, comma)).c_str()),
          std::atoi(std::string(text.substr(comma + 1)).c_str())};
}

int play(const std::string& recording, const std::vector<int>& cams, const std::vector<int>& outs,
         const std::string& keys) {
  const recording::EurocRecording rec = recording::read_euroc(recording);
  const auto& f0 = rec.cams[0].frames;
  const auto& f1 = rec.cams[1].frames;
  const std::size_t n = std::min(f0.size(), f1.size());
  if (n < 2) fail(recording + ": fewer than two stereo frames");
  const DurationNs period_ns = (f0[n - 1].t_ns - f0[0].t_ns) / static_cast<DurationNs>(n - 1);
  if (std::abs(period_ns - kFramePeriodNs) > kFramePeriodNs / 100) {
    fail(recording + ": frames every " + std::to_string(period_ns / 1000) +
         " us; vivid plays at 20 Hz (50000 us)");
  }
  std::vector<std::array<Image, 2>> frames(n);
  for (std::size_t i = 0; i < n; ++i) {
    frames[i][0] = recording::load_png_gray(rec.cams[0].image_path(f0[i]), kWidth, kHeight);
    frames[i][1] = recording::load_png_gray(rec.cams[1].image_path(f1[i]), kWidth, kHeight);
  }
  std::printf("hil-rig: %zu stereo frames of %s loaded\n", n, recording.c_str());

  std::array<Output, 2> out{Output("/dev/video" + std::to_string(outs[0])),
                            Output("/dev/video" + std::to_string(outs[1]))};
  std::unique_ptr<Keyboard> keyboard;
  if (!keys.empty()) keyboard = std::make_unique<Keyboard>(keys);

  std::uint64_t next = 0;  // the k-th pair the next queued buffers carry (pair frame_of(k))
  std::uint64_t reconnects = 0;
  std::uint64_t loops = 0;
  // Forth and back (0 .. n-1 .. 1, 0 ..): consecutive pairs are always neighbours in the
  // recording, also across the loop, so a pair whose two sides straddle a frame change holds
  // two neighbouring recorded images, never the recording's last and first.
  const auto frame_of = [n](std::uint64_t k) {
    const std::uint64_t period = 2 * (n - 1);
    const std::uint64_t j = k % period;
    return static_cast<std::size_t>(j < n ? j : period - j);
  };
  // Both outputs set up first, then started back to back: vivid's output threads tick from
  // their STREAMON, so the two sides change frames within a jiffy of each other (set up one
  // after the other under emulation, they were ~40 ms apart and most pairs mixed two frames).
  auto start_both = [&] {
    for (int side = 0; side < 2; ++side) {
      out[side].close();
      try {
        if (!out[side].open()) return false;
      } catch (const std::exception& e) {  // opened while vivid was still reconnecting
        std::fprintf(stderr, "hil-rig: %s\n", e.what());
        return false;
      }
      for (std::uint32_t i = 0; i < out[side].buffers(); ++i) {
        if (!out[side].queue(i, frames[frame_of(next + i)][side])) return false;
      }
    }
    if (!out[0].stream_on() || !out[1].stream_on()) return false;
    next += kBuffers;
    return true;
  };
  for (int side = 0; side < 2; ++side) {
    configure_capture("/dev/video" + std::to_string(cams[side]));
  }
  if (!start_both()) fail(err(out[0].path() + ", " + out[1].path() + ": streaming"));
  sd_notify(0, "READY=1");
  std::printf("hil-rig: streaming %s and %s\n", out[0].path().c_str(), out[1].path().c_str());
  std::fflush(stdout);

  auto report = [&] {
    std::printf(
        "hil-rig: queued %llu left, %llu right, %llu loops, %llu reconnects, "
        "%llu key presses\n",
        static_cast<unsigned long long>(out[0].queued),
        static_cast<unsigned long long>(out[1].queued), static_cast<unsigned long long>(loops),
        static_cast<unsigned long long>(reconnects),
        static_cast<unsigned long long>(keyboard ? keyboard->presses : 0));
    std::fflush(stdout);
  };
  // Buffers handed back by one side, waiting for the other side's (frame i goes to both).
  std::array<std::vector<int>, 2> free_bufs;
  while (!g_stop.load()) {
    if (g_press.exchange(false) && keyboard) keyboard->press(KEY_R);
    if (g_report.exchange(false)) report();
    if (out[0].lost || out[1].lost) {
      // Disconnected: close both (vivid reconnects an instance once every handle on it is
      // closed), then restart both together from the current frame, in step again.
      const int gone = out[0].lost ? 0 : 1;
      free_bufs[0].clear();
      free_bufs[1].clear();
      if (start_both()) {
        out[0].lost = out[1].lost = false;
        ++reconnects;
        std::printf("hil-rig: %s back after a disconnect\n", out[gone].path().c_str());
        std::fflush(stdout);
      } else {
        out[0].close();
        out[1].close();
        out[gone].lost = true;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        continue;
      }
    }
    std::array<pollfd, 2> p{};
    for (int side = 0; side < 2; ++side) p[side] = {out[side].fd(), POLLOUT, 0};
    if (::poll(p.data(), 2, 200) <= 0) continue;
    for (int side = 0; side < 2; ++side) {
      if (out[side].lost || out[side].fd() < 0) continue;
      const int b = out[side].dequeue();
      if (b >= 0) free_bufs[side].push_back(b);
    }
    // A lost side does not hold the other one back.
    while (true) {
      const bool l = !free_bufs[0].empty() || out[0].lost;
      const bool r = !free_bufs[1].empty() || out[1].lost;
      if (!l || !r || (out[0].lost && out[1].lost)) break;
      for (int side = 0; side < 2; ++side) {
        if (free_bufs[side].empty()) continue;
        const int b = free_bufs[side].front();
        free_bufs[side].erase(free_bufs[side].begin());
        if (!out[side].queue(static_cast<std::uint32_t>(b), frames[frame_of(next)][side])) {
          out[side].lost = true;
        }
      }
      ++next;
      if (next % (2 * (n - 1)) == 0) ++loops;
    }
  }
  report();
  return 0;
}

int ctrl(const std::string& path, std::uint32_t id, std::int32_t value) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) fail(err(path));
  set_ctrl(fd, id, value, path);
  ::close(fd);
  return 0;
}

/// Which recorded pair each captured pair carries: every captured image is compared with the
/// recording's images of the same side (mean absolute difference; 0 = bit-identical).
int match(const std::string& recording, const std::string& captured) {
  const recording::EurocRecording src = recording::read_euroc(recording);
  const recording::EurocRecording cap = recording::read_euroc(captured);
  const std::size_t n = std::min(src.cams[0].frames.size(), src.cams[1].frames.size());
  std::array<std::vector<Image>, 2> images;
  for (int side = 0; side < 2; ++side) {
    for (std::size_t i = 0; i < n; ++i) {
      images[side].push_back(recording::load_png_gray(
          src.cams[side].image_path(src.cams[side].frames[i]), kWidth, kHeight));
    }
  }
  auto mad = [](const Image& a, const Image& b) {
    std::uint64_t sum = 0;
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x)
        sum += static_cast<std::uint64_t>(std::abs(a.row(y)[x] - b.row(y)[x]));
    }
    return static_cast<double>(sum) / (kWidth * kHeight);
  };
  // The recording's two streams are written separately (a writer that falls behind drops
  // frames of either), so the pairs are found again by time: each left frame with the right
  // one nearest it, within half a frame period.
  std::vector<std::array<std::size_t, 2>> pair_index;
  const auto& right = cap.cams[1].frames;
  for (std::size_t k = 0; k < cap.cams[0].frames.size(); ++k) {
    const TimeNs t = cap.cams[0].frames[k].t_ns;
    std::size_t best = right.size();
    for (std::size_t j = 0; j < right.size(); ++j) {
      if (std::abs(right[j].t_ns - t) <= kFramePeriodNs / 2 &&
          (best == right.size() || std::abs(right[j].t_ns - t) < std::abs(right[best].t_ns - t))) {
        best = j;
      }
    }
    if (best < right.size()) pair_index.push_back({k, best});
  }
  const std::size_t pairs = pair_index.size();
  std::size_t identical = 0, same_pair = 0;
  double worst = 0.0;
  for (std::size_t k = 0; k < pairs; ++k) {
    std::array<std::size_t, 2> best_i{};
    for (int side = 0; side < 2; ++side) {
      const Image got = recording::load_png_gray(
          cap.cams[side].image_path(cap.cams[side].frames[pair_index[k][side]]), kWidth, kHeight);
      double best = 1e9;
      for (std::size_t i = 0; i < n; ++i) {
        const double d = mad(got, images[side][i]);
        if (d < best) {
          best = d;
          best_i[side] = i;
        }
      }
      worst = std::max(worst, best);
      if (best == 0.0) ++identical;
    }
    if (best_i[0] == best_i[1]) ++same_pair;
  }
  std::printf(
      "hil-rig: %zu captured pairs: %zu of %zu images bit-identical to a recorded one "
      "(worst mean difference %.3f grey levels), %zu pairs carry one recorded pair\n",
      pairs, identical, 2 * pairs, worst, same_pair);
  return 0;
}

int usage() {
  std::fprintf(stderr,
               "usage: wallar_hil_rig play RECORDING [--cams 0,2] [--outs 1,3] [--keys NAME]\n"
               "       wallar_hil_rig ctrl /dev/videoN ID VALUE\n"
               "       wallar_hil_rig match RECORDING CAPTURED\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  if (argc < 3) return usage();
  struct sigaction sa {};
  sa.sa_handler = on_stop;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  sa.sa_handler = on_press;
  sigaction(SIGUSR1, &sa, nullptr);
  sa.sa_handler = on_report;
  sigaction(SIGUSR2, &sa, nullptr);
  try {
    const std::string_view cmd = argv[1];
    if (cmd == "match" && argc == 4) return match(argv[2], argv[3]);
    if (cmd == "ctrl" && argc == 5) {
      return ctrl(argv[2], static_cast<std::uint32_t>(std::strtoul(argv[3], nullptr, 0)),
                  static_cast<std::int32_t>(std::strtol(argv[4], nullptr, 0)));
    }
    if (cmd != "play") return usage();
    std::vector<int> cams{0, 2};
    std::vector<int> outs{1, 3};
    std::string keys;
    for (int i = 3; i < argc; i += 2) {
      const std::string_view a = argv[i];
      if (i + 1 >= argc) return usage();
      if (a == "--cams") {
        cams = parse_pair(argv[i + 1]);
      } else if (a == "--outs") {
        outs = parse_pair(argv[i + 1]);
      } else if (a == "--keys") {
        keys = argv[i + 1];
      } else {
        return usage();
      }
    }
    return play(argv[2], cams, outs, keys);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hil-rig: %s\n", e.what());
    return 1;
  }
}
