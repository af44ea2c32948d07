// SPDX-License-Identifier: Apache-2.0
/// @file test_alloc.cpp
/// @brief Counts heap allocations on the fixed-rate paths: after setup, a wall detection
/// allocates nothing, nor does an attitude-filter update, nor do the BNO055 UART and ICM-20948
/// drivers' step() in RUN, nor does stereo capture (poll, DQBUF, pairing, mailbox, re-queue,
/// a stream restart) after start(), nor does the tracker over 100 frames (key-frames and map
/// corrections included). Its own executable: it replaces the global operator new.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <new>
#include <opencv2/core.hpp>

#include "bno055_rig.hpp"
#include "fake_v4l2.hpp"
#include "imu_rig.hpp"
#include "wallar/core/mailbox.hpp"
#include "wallar/drivers/camera/stereo_capture.hpp"
#include "wallar/dsp/imu/attitude_filter.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/tracking/synthetic_motion.hpp"
#include "wallar/dsp/tracking/synthetic_room.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/dsp/walls/synthetic.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"

namespace {
thread_local bool g_counting = false;
thread_local std::size_t g_allocations = 0;

// Counts the allocations made on this thread between construction and count().
class AllocationCounter {
 public:
  AllocationCounter() {
    g_allocations = 0;
    g_counting = true;
  }
  ~AllocationCounter() { g_counting = false; }
  std::size_t count() const { return g_allocations; }
};

// Under an emulator (tests/CMakeLists.txt sets WALLAR_SHORT_TESTS) the slow tests do less.
bool short_run() { return std::getenv("WALLAR_SHORT_TESTS") != nullptr; }
}  // namespace

// The C allocator itself is counted (malloc, calloc, realloc, the aligned ones), not only
// operator new: Eigen's dynamic matrices and OpenCV's cv::Mat (fastMalloc: posix_memalign)
// allocate through it and were invisible to an operator-new counter. glibc's own entry points
// (__libc_*) do the work. Sanitizer builds keep their interceptors.
#if !defined(WALLAR_SANITIZED)
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);

void* malloc(std::size_t size) noexcept {
  if (g_counting) ++g_allocations;
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  if (g_counting) ++g_allocations;
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) noexcept {
  if (g_counting) ++g_allocations;
  return __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  if (g_counting) ++g_allocations;
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  if (g_counting) ++g_allocations;
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  if (g_counting) ++g_allocations;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
}
#define WALLAR_COUNTS_MALLOC 1
#endif

void* operator new(std::size_t size) {
#if !defined(WALLAR_COUNTS_MALLOC)
  if (g_counting) ++g_allocations;
#endif
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t al) {
#if !defined(WALLAR_COUNTS_MALLOC)
  if (g_counting) ++g_allocations;
#endif
  const auto a = static_cast<std::size_t>(al);
  if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t al) { return operator new(size, al); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

namespace wallar::dsp {
namespace {

TEST(Allocations, TheCounterSeesAllocations) {
  AllocationCounter counter;
  auto* v = new std::vector<int>(100);
  delete v;
  EXPECT_EQ(counter.count(), 2u);  // the vector and its buffer: the counter works
}

#if defined(WALLAR_COUNTS_MALLOC)
// Eigen's dynamic matrices and OpenCV's images allocate through the C allocator.
TEST(Allocations, TheCounterSeesTheCAllocatorsToo) {
  AllocationCounter counter;
  void* p = std::malloc(16);
  std::free(p);
  EXPECT_EQ(counter.count(), 1u);
  Eigen::MatrixXd m(40, 40);  // Eigen's aligned malloc
  m.setZero();
  EXPECT_EQ(counter.count(), 2u);
  cv::Mat image(48, 64, CV_8UC1);  // fastMalloc (posix_memalign) and its header
  EXPECT_GE(counter.count(), 3u);
}
#endif

TEST(Allocations, WallDetectionAllocatesNothingAfterSetup) {
  const auto map = make_sparse_map({});
  const Eigen::Vector3d gravity(0.0, 9.81, 0.0);
  for (ScoreMethod method :
       {ScoreMethod::kRansac, ScoreMethod::kMsac, ScoreMethod::kBsf, ScoreMethod::kBinomial}) {
    DetectorConfig cfg;
    cfg.method = method;
    cfg.threshold_m = 0.03;
    // The same code paths on fewer rounds under an emulator (plain RANSAC would run ~100,000).
    if (short_run()) cfg.max_rounds = 10'000;
    WallDetector det(map.cloud.size(), cfg);  // setup: allocates
    const std::array<Eigen::Vector3d, 2> viewpoints{Eigen::Vector3d::Zero(),
                                                    Eigen::Vector3d(0.1, 0.0, 0.0)};
    AllocationCounter counter;
    det.set_viewpoints(viewpoints);
    det.set_points(map.cloud, gravity);
    const Detection vertical = det.detect_vertical();
    const Detection horizontal = det.detect_horizontal();
    det.set_points(map.cloud);
    const Detection d3 = det.detect_3d();
    det.remove_inliers(d3.plane);
    const Detection again = det.detect_3d();
    EXPECT_EQ(counter.count(), 0u) << "method " << static_cast<int>(method);
    EXPECT_TRUE(vertical.found);
    EXPECT_TRUE(horizontal.found);
    EXPECT_TRUE(d3.found);
    EXPECT_TRUE(again.found);
  }
}

TEST(Allocations, AttitudeFilterUpdateAllocatesNothingAfterConstruction) {
  // A moving first window (refused and slid), a still one (initialisation), then turning with a
  // magnetometer (used and refused): every path of update().
  std::vector<ImuSample> samples(1200);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double t_s = static_cast<double>(i) / 200.0;
    ImuSample& s = samples[i];
    s.t_ns = static_cast<TimeNs>(i) * 5 * kNsPerMs;
    const double turn = i < 100 ? 2.0 * std::sin(40.0 * t_s) : (i < 500 ? 0.0 : 0.3);
    s.gyro_rad_s = Eigen::Vector3d(turn, 0.01, -0.02);
    s.accel_m_s2 = Eigen::Vector3d(0.01 * std::sin(t_s), 0.0, 9.81);
    if (i >= 600)
      s.mag_uT = Eigen::Vector3d(24.0 * std::cos(0.3 * t_s), 24.0 * std::sin(0.3 * t_s), -41.6);
  }
  AttitudeFilter filter;  // setup: allocates the still window
  AllocationCounter counter;
  for (const ImuSample& s : samples) filter.update(s);
  EXPECT_EQ(counter.count(), 0u);
  EXPECT_TRUE(filter.initialized());
  EXPECT_GE(filter.counters().init_windows_rejected, 1u);
  // The readings turn about z while the gyro turns about x: some fit the prediction (used),
  // the others fall outside the heading gate (refused): both paths ran.
  EXPECT_GT(filter.counters().mag_updates, 50u);
  EXPECT_GT(filter.counters().mag_rejected, 50u);
  EXPECT_EQ(filter.counters().mag_updates + filter.counters().mag_rejected + 1, 600u);
}

}  // namespace
}  // namespace wallar::dsp

namespace wallar::drivers {
namespace {

// Only the driver's step() is counted: the simulator on the other end of the pty allocates.
TEST(Allocations, Bno055UartStepsInRunAllocateNothing) {
  test::Bno055Rig rig;
  rig.sink.samples.reserve(4096);
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);  // warm-up
  const std::uint64_t samples_before = rig.counters().samples;
  std::size_t steps = 0;
  std::size_t allocations = 0;
  const TimeNs end = rig.now + kNsPerS;
  while (rig.now < end) {
    if (steps == 60) rig.sim.garbage_next = 5;        // the resync path too
    if (steps == 120) rig.sim.status_next_count = 1;  // and an error status
    TimeNs wake = 0;
    {
      AllocationCounter counter;
      wake = rig.step_driver();
      allocations += counter.count();
    }
    rig.answer_and_advance(wake);
    ++steps;
  }
  EXPECT_EQ(allocations, 0u) << steps << " steps";
  EXPECT_GT(rig.counters().samples, samples_before + 90);  // they did real work
  EXPECT_EQ(rig.driver->state(), ImuDriverState::kRun);
  EXPECT_GE(rig.counters().resync, 1u);
  EXPECT_GE(rig.counters().nack, 1u);
}

}  // namespace
}  // namespace wallar::drivers

namespace wallar::test {
namespace {

TEST(Allocations, Icm20948StepAllocatesNothingInRun) {
  ImuRig rig;
  rig.sim.set_logging(false);
  rig.sim.reserve(20000);
  rig.sink.samples.reserve(20000);
  rig.sink.no_grow = true;
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), drivers::ImuDriverState::kRun);
  const std::uint64_t before = rig.driver.counters().samples;
  std::size_t allocations = 0;
  {
    AllocationCounter counter;
    rig.run_until(1100 * kNsPerMs);  // ~1125 steps with FIFO reads, mag reads, re-checks
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(rig.driver.state(), drivers::ImuDriverState::kRun);
  EXPECT_GT(rig.driver.counters().samples - before, 1000u);
  EXPECT_TRUE(std::any_of(rig.sink.samples.begin(), rig.sink.samples.end(),
                          [](const ImuSample& s) { return s.mag_uT.has_value(); }));
}

}  // namespace
}  // namespace wallar::test

namespace wallar::test {
namespace {

// Capture -> pairing -> newest-only mailbox -> consumer, all on this thread.
TEST(Allocations, StereoCaptureAllocatesNothingAfterStart) {
  for (drivers::CameraPixelFormat format :
       {drivers::CameraPixelFormat::kGrey, drivers::CameraPixelFormat::kYuyv}) {
    FakeV4l2 sys;
    FakeV4l2Device& left = sys.add_device("/dev/video0");
    sys.add_device("/dev/video2");
    std::array<drivers::V4l2CameraConfig, 2> configs;
    configs[0].device = "/dev/video0";
    configs[1].device = "/dev/video2";
    for (auto& c : configs) {
      c.width_px = 64;
      c.height_px = 48;
      c.format = format;
    }
    MailboxSink sink;
    drivers::StereoCapture capture(sys, configs, sink);
    capture.start();
    StereoFrame taken;
    int pairs = 0;
    for (int i = 0; i < 50; ++i) capture.run_once(100 * kNsPerMs);  // warm up
    std::size_t allocations = 0;
    {
      AllocationCounter counter;
      while (pairs < 100) {
        capture.run_once(100 * kNsPerMs);
        if (!sink.box.take(taken)) continue;
        if (++pairs == 50) {
          left.stall_until_restart();  // the restart rung of the recovery ladder too
          left.eagain_storm(3);
        }
      }
      taken = StereoFrame{};
      allocations = counter.count();
    }
    EXPECT_EQ(allocations, 0u) << "format " << static_cast<int>(format);
    EXPECT_EQ(capture.camera(0).counters().stream_restarts, 1u);
    EXPECT_GE(capture.pairing().pairs, 100u);
  }
}

}  // namespace
}  // namespace wallar::test

TEST(Allocations, TrackerTracksAHundredFramesWithoutAllocating) {
  using namespace wallar;
  const dsp::SyntheticRoom room = dsp::small_room();
  const dsp::SyntheticCamera cam;
  const RigCalibration rig = dsp::synthetic_rig(cam);
  // 25 poses of a moving path, played forth and back: key-frames, re-finding and corrections
  // (under an emulator, where rendering is slow, the first 10 of them).
  const int poses = short_run() ? 10 : 25;
  const std::vector<StampedPose> path = dsp::synthetic_trajectory(room, poses, 5.0);
  std::vector<std::array<Image, 2>> pairs;
  for (const StampedPose& p : path) {
    pairs.push_back({dsp::render_room_image(room, cam, p.T_world_body, 0),
                     dsp::render_room_image(room, cam, p.T_world_body, 1)});
  }
  dsp::Tracker tracker(rig, dsp::TrackerConfig{});
  dsp::Mapper mapper(tracker.intrinsics());
  dsp::MapCorrection correction(20000, 256);
  std::size_t allocations = 0, keyframes = 0;
  int tracking = 0;
  for (int k = 0; k < 100; ++k) {
    const int period = 2 * poses - 2;  // 0..poses-1, then back down to 1
    const int cycle = k % period;
    const std::size_t i = static_cast<std::size_t>(cycle < poses ? cycle : period - cycle);
    const TimeNs t_ns = static_cast<TimeNs>(k) * 200'000'000;
    dsp::TrackResult r;
    {
      AllocationCounter counter;
      r = tracker.track(t_ns, pairs[i][0], pairs[i][1]);
      allocations += counter.count();
    }
    tracking += r.state == dsp::TrackingState::kTracking ? 1 : 0;
    if (const dsp::KeyframeMessage* kf = tracker.pending_keyframe()) {
      ++keyframes;
      mapper.add_keyframe(*kf);  // the mapping thread's work: it may allocate
      mapper.local_adjust(correction);
      AllocationCounter counter;
      tracker.apply(correction);
      allocations += counter.count();
    }
  }
  EXPECT_EQ(tracking, 100);
  EXPECT_GE(keyframes, short_run() ? 2u : 3u);  // the path is long enough for the map to grow
  EXPECT_EQ(allocations, 0u);
}
