// SPDX-License-Identifier: Apache-2.0
/// @file test_device_clock.cpp
/// @brief The device clock model: a fast or slow oscillator seen through late, jittery
/// observations is mapped to the true sample times; gaps re-anchor it.
#include <gtest/gtest.h>

#include <cstdint>

#include "wallar/drivers/imu/device_clock.hpp"

namespace wallar::drivers {
namespace {

// Deterministic latency in [0, max_ns): a 64-bit LCG (no std distributions: the same numbers
// on every architecture).
struct Latency {
  std::uint64_t state = 12345;
  DurationNs next(DurationNs max_ns) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<DurationNs>((state >> 33) % static_cast<std::uint64_t>(max_ns));
  }
};

constexpr DurationNs kNominal = 5 * kNsPerMs;  // 200 Hz

TEST(DeviceClock, FollowsASlowOscillatorThroughJitteryObservations) {
  const double true_period = 1.01 * kNominal;  // 1 % slow
  const TimeNs t0 = 1'000'000'000;
  DeviceClock clock(kNominal);
  Latency latency;
  DurationNs worst_after_window = 0;
  double sum_after_window = 0.0;
  for (std::uint64_t k = 0; k < 2000; ++k) {
    const TimeNs t_true = t0 + static_cast<TimeNs>(static_cast<double>(k) * true_period);
    clock.observe(k, t_true + 50'000 + latency.next(400'000));  // 50..450 us late
    const DurationNs err = clock.time_of(k) - t_true;
    // Until the slope is known the nominal period (1 % short) is carried a few samples.
    EXPECT_GE(err, k < 64 ? -250'000 : 0) << "k=" << k << ": a stamp before the sample";
    if (k >= 64) {
      worst_after_window = std::max(worst_after_window, err);
      sum_after_window += static_cast<double>(err);
    }
  }
  // What remains is the least latency in the window (50 us plus a little), not the
  // observations' mean latency (250 us) nor their worst (450 us).
  EXPECT_LT(sum_after_window / (2000 - 64), 80'000.0);
  EXPECT_LT(worst_after_window, 200'000);
  EXPECT_NEAR(clock.period_ns(), true_period, 0.001 * kNominal);
  EXPECT_EQ(clock.gaps(), 0u);
}

TEST(DeviceClock, AKnownLatencyIsSubtractedAndAStallReanchors) {
  DeviceClock clock(kNominal, 0.05, 200'000);
  for (std::uint64_t k = 0; k < 100; ++k) {
    clock.observe(k, static_cast<TimeNs>(k) * kNominal + 200'000);
  }
  EXPECT_EQ(clock.time_of(99), 99 * kNominal);
  // The device stalls for 1 s and restarts its samples from a new phase.
  const TimeNs t_restart = 99 * kNominal + kNsPerS + 1'234'567;
  clock.observe(100, t_restart + 200'000);
  EXPECT_EQ(clock.gaps(), 1u);
  EXPECT_EQ(clock.time_of(100), t_restart);
  EXPECT_EQ(clock.time_of(101), t_restart + kNominal);
  clock.reset();
  EXPECT_FALSE(clock.valid());
}

TEST(DeviceClock, ThePeriodStaysWithinTheOscillatorsTolerance) {
  DeviceClock clock(kNominal, 0.02);
  // Observations claiming a 10 % fast clock (a stalled reader catching up, say).
  for (std::uint64_t k = 0; k < 200; ++k) clock.observe(k, static_cast<TimeNs>(k) * 4'500'000);
  EXPECT_NEAR(clock.period_ns(), 0.98 * kNominal, 1.0);
}

}  // namespace
}  // namespace wallar::drivers
