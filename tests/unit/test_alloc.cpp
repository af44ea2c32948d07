// SPDX-License-Identifier: Apache-2.0
/// @file test_alloc.cpp
/// @brief Counts heap allocations on the fixed-rate paths: after setup, a wall detection
/// allocates nothing, nor does the ICM-20948 driver's step() in RUN. Its own executable: it
/// replaces the global operator new.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <new>

#include "imu_rig.hpp"
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
}  // namespace

void* operator new(std::size_t size) {
  if (g_counting) ++g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t al) {
  if (g_counting) ++g_allocations;
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

TEST(Allocations, WallDetectionAllocatesNothingAfterSetup) {
  const auto map = make_sparse_map({});
  const Eigen::Vector3d gravity(0.0, 9.81, 0.0);
  for (ScoreMethod method :
       {ScoreMethod::kRansac, ScoreMethod::kMsac, ScoreMethod::kBsf, ScoreMethod::kBinomial}) {
    DetectorConfig cfg;
    cfg.method = method;
    cfg.threshold_m = 0.03;
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

}  // namespace
}  // namespace wallar::dsp

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
