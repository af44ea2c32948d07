// SPDX-License-Identifier: Apache-2.0
/// @file async_recorder.cpp
/// @brief Two SPSC rings into one writer thread; producers copy or reference, never wait.
#include "wallar/drivers/source/async_recorder.hpp"

#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <exception>
#include <mutex>
#include <thread>

#include "wallar/core/spsc_ring.hpp"

namespace wallar::source {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kIdleSleep = std::chrono::milliseconds(2);
constexpr auto kFullWait = std::chrono::microseconds(200);

// Pixel memory owned by one ring slot. The slot's Image references it while it holds a copy;
// when that reference goes nothing is freed: the memory is the slot's until the ring goes.
class SlotPixels final : public ImageBuffer {
 public:
  explicit SlotPixels(std::size_t size_bytes)
      : storage_(std::make_unique<std::uint8_t[]>(size_bytes)) {  // zeroed: pages touched now
    set_memory(storage_.get(), size_bytes);
  }
  ~SlotPixels() override = default;
  SlotPixels(const SlotPixels&) = delete;
  SlotPixels& operator=(const SlotPixels&) = delete;

 private:
  void release() override {}
  std::unique_ptr<std::uint8_t[]> storage_;
};

// One ring slot: a stereo pair (cam < 0) or one unpaired frame of camera `cam`.
struct FrameSlot {
  std::array<std::unique_ptr<SlotPixels>, 2> pixels;  // declared first: outlives `frames`
  std::array<CameraFrame, 2> frames;
  TimeNs t_ns = 0;
  int cam = -1;
};

// Raises a high-water mark; only the ring's producer writes it.
void raise(std::atomic<std::uint64_t>& mark, std::size_t value) {
  if (value > mark.load(std::memory_order_relaxed)) mark.store(value, std::memory_order_relaxed);
}

std::string one_line(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  std::replace(text.begin(), text.end(), '\r', ' ');
  return text;
}

}  // namespace

struct AsyncRecorder::State {
  State(recording::RecordingWriter& w, const AsyncRecorderOptions& o)
      : writer(w),
        options(o),
        imu(std::max<std::size_t>(o.imu_capacity, 1)),
        frames(std::max<std::size_t>(o.frame_capacity, 1), [&o] {
          FrameSlot slot;
          if (o.copy_frames) {
            for (std::size_t i = 0; i < 2; ++i) {
              const std::size_t bytes = static_cast<std::size_t>(std::max(o.width_px[i], 0)) *
                                        static_cast<std::size_t>(std::max(o.height_px[i], 0));
              if (bytes > 0) slot.pixels[i] = std::make_unique<SlotPixels>(bytes);
            }
          }
          return slot;
        }) {}

  recording::RecordingWriter& writer;
  const AsyncRecorderOptions options;
  SpscRing<ImuSample> imu;
  SpscRing<FrameSlot> frames;

  // Producers: a call is "in flight" from before it checks `accepting` until after its push,
  // so the writer, once `stop` is set and nothing is in flight, has seen every push.
  std::atomic<bool> accepting{true};
  std::atomic<bool> stop{false};
  std::atomic<int> in_flight{0};

  std::atomic<std::uint64_t> imu_written{0};
  std::array<std::atomic<std::uint64_t>, 2> frames_written{};
  std::atomic<std::uint64_t> pairs_written{0};
  std::atomic<std::uint64_t> imu_dropped{0};
  std::atomic<std::uint64_t> frames_dropped{0};
  std::atomic<std::uint64_t> imu_high_water{0};
  std::atomic<std::uint64_t> frame_high_water{0};
  std::atomic<std::uint64_t> write_errors{0};
  std::atomic<std::uint64_t> frames_not_copied{0};

  bool failed = false;  // writer thread only
  mutable std::mutex error_mutex;
  std::string error;  // guarded by error_mutex

  std::mutex close_mutex;
  bool closed = false;  // guarded by close_mutex
  std::thread thread;

  // ---- producers ------------------------------------------------------------------------------

  // Fills `dst` from `src`: a copy into `pixels` when it fits, else a counted reference.
  void fill(CameraFrame& dst, SlotPixels* pixels, const CameraFrame& src) {
    dst.t_ns = src.t_ns;
    dst.publish_t_ns = src.publish_t_ns;
    dst.sequence = src.sequence;
    const Image& im = src.image;
    if (!options.copy_frames || im.empty()) {
      dst.image = im;
      return;
    }
    const int row_bytes = im.width() * bytes_per_pixel(im.format());
    const std::size_t bytes = static_cast<std::size_t>(std::max(row_bytes, 0)) *
                              static_cast<std::size_t>(std::max(im.height(), 0));
    if (pixels == nullptr || bytes == 0 || bytes > pixels->size_bytes()) {
      frames_not_copied.fetch_add(1, std::memory_order_relaxed);
      dst.image = im;
      return;
    }
    std::uint8_t* out = pixels->mutable_data();
    if (im.stride_bytes() == row_bytes) {
      std::memcpy(out, im.data(), bytes);
    } else {
      for (int y = 0; y < im.height(); ++y)
        std::memcpy(out + std::ptrdiff_t{y} * row_bytes, im.row(y),
                    static_cast<std::size_t>(row_bytes));
    }
    dst.image = Image(pixels, im.width(), im.height(), row_bytes, im.format());
  }

  // The next free slot of `ring`, or null (the caller drops) when the recorder is closing or
  // the ring is full and waiting is not allowed.
  template <typename T>
  T* slot_of(SpscRing<T>& ring) {
    if (!accepting.load()) return nullptr;
    T* slot = ring.producer_slot();
    while (slot == nullptr && options.wait_when_full && accepting.load(std::memory_order_relaxed)) {
      std::this_thread::sleep_for(kFullWait);
      slot = ring.producer_slot();
    }
    return slot;
  }

  void push_imu(const ImuSample& s) noexcept {
    in_flight.fetch_add(1);
    if (ImuSample* slot = slot_of(imu)) {
      *slot = s;  // optional<> members: plain copies, no heap
      imu.push();
      raise(imu_high_water, imu.size_approx());
    } else {
      imu_dropped.fetch_add(1, std::memory_order_relaxed);
    }
    in_flight.fetch_sub(1);
  }

  void push_frames(int cam, const CameraFrame* left, const CameraFrame* right, TimeNs t_ns) {
    in_flight.fetch_add(1);
    if (FrameSlot* slot = slot_of(frames)) {
      slot->cam = cam;
      slot->t_ns = t_ns;
      if (left != nullptr) fill(slot->frames[0], slot->pixels[0].get(), *left);
      if (right != nullptr) fill(slot->frames[1], slot->pixels[1].get(), *right);
      frames.push();
      raise(frame_high_water, frames.size_approx());
    } else {
      frames_dropped.fetch_add(cam < 0 ? 2 : 1, std::memory_order_relaxed);
    }
    in_flight.fetch_sub(1);
  }

  // ---- writer thread --------------------------------------------------------------------------

  // Runs one write; a failure is kept (the first, as one line) and ends all further writing.
  template <typename Write>
  bool attempt(Write&& write) {
    if (failed) {
      write_errors.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    try {
      write();
      return true;
    } catch (const std::exception& e) {
      fail(e.what());
    } catch (...) {
      fail("unknown error while writing the recording");
    }
    write_errors.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  void fail(const char* what) {
    failed = true;
    std::lock_guard lock(error_mutex);
    if (error.empty()) error = one_line(what);
  }

  void write_slot(FrameSlot& slot) {
    bool both = slot.cam < 0;
    for (int c = 0; c < 2; ++c) {
      if (slot.cam >= 0 && slot.cam != c) continue;
      CameraFrame& f = slot.frames[static_cast<std::size_t>(c)];
      if (attempt([&] { writer.write_camera(c, f); })) {
        frames_written[static_cast<std::size_t>(c)].fetch_add(1, std::memory_order_relaxed);
      } else {
        both = false;
      }
      f.image = Image();  // give a referenced source buffer back now, on this thread
    }
    if (both) pairs_written.fetch_add(1, std::memory_order_relaxed);
  }

  void run() noexcept {
    pthread_setname_np(pthread_self(), "recorder");
    for (;;) {
      ImuSample* s = imu.front();
      FrameSlot* f = frames.front();
      if (s == nullptr && f == nullptr) {
        // Done once stopped, no producer call is between its check and its push, and both
        // rings are (still) empty. Every load here is sequentially consistent.
        if (stop.load() && in_flight.load() == 0) {
          if (imu.front() == nullptr && frames.front() == nullptr) break;
          continue;
        }
        std::this_thread::sleep_for(kIdleSleep);
        continue;
      }
      if (s != nullptr && (f == nullptr || s->t_ns <= f->t_ns)) {
        if (attempt([&] { writer.write_imu(*s); }))
          imu_written.fetch_add(1, std::memory_order_relaxed);
        imu.pop();
      } else {
        write_slot(*f);
        frames.pop();
      }
    }
    // Flush and fsync. A failure here (none today: EurocWriter::close() does not throw) is
    // reported but loses no counted sample.
    if (!options.close_writer) return;
    try {
      writer.close();
    } catch (const std::exception& e) {
      fail(e.what());
    } catch (...) {
      fail("unknown error while closing the recording");
    }
  }
};

AsyncRecorder::AsyncRecorder(recording::RecordingWriter& writer,
                             const AsyncRecorderOptions& options)
    : state_(std::make_unique<State>(writer, options)) {
  state_->thread = std::thread([s = state_.get()] { s->run(); });
}

AsyncRecorder::~AsyncRecorder() {
  try {
    (void)close();
  } catch (...) {  // std::thread::join failing: nothing left to do in a destructor
  }
}

void AsyncRecorder::on_imu(const ImuSample& sample) { state_->push_imu(sample); }
void AsyncRecorder::on_imu_sample(const ImuSample& sample) noexcept { state_->push_imu(sample); }

void AsyncRecorder::on_stereo(const StereoFrame& frame) {
  state_->push_frames(-1, &frame.left, &frame.right, frame.t_ns);
}

void AsyncRecorder::on_unpaired(int cam, const CameraFrame& frame) {
  if (cam != 0 && cam != 1) {
    state_->frames_dropped.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  state_->push_frames(cam, cam == 0 ? &frame : nullptr, cam == 1 ? &frame : nullptr, frame.t_ns);
}

RecorderCounters AsyncRecorder::close() {
  State& s = *state_;
  std::lock_guard lock(s.close_mutex);
  if (!s.closed) {
    s.accepting.store(false);
    s.stop.store(true);
    if (s.thread.joinable()) s.thread.join();
    s.closed = true;
  }
  return counters();
}

RecorderCounters AsyncRecorder::counters() const {
  const State& s = *state_;
  constexpr auto kRelaxed = std::memory_order_relaxed;
  RecorderCounters c;
  c.imu_written = s.imu_written.load(kRelaxed);
  c.frames_written = {s.frames_written[0].load(kRelaxed), s.frames_written[1].load(kRelaxed)};
  c.pairs_written = s.pairs_written.load(kRelaxed);
  c.imu_dropped = s.imu_dropped.load(kRelaxed);
  c.frames_dropped = s.frames_dropped.load(kRelaxed);
  c.imu_high_water = s.imu_high_water.load(kRelaxed);
  c.frame_high_water = s.frame_high_water.load(kRelaxed);
  c.write_errors = s.write_errors.load(kRelaxed);
  c.frames_not_copied = s.frames_not_copied.load(kRelaxed);
  {
    std::lock_guard lock(s.error_mutex);
    c.error = s.error;
  }
  return c;
}

}  // namespace wallar::source
