// SPDX-License-Identifier: Apache-2.0
/// @file test_allan_variance.cpp
/// @brief The Allan deviation against its closed forms, and the noise terms read back from a
/// still IMU's stream generated with known densities (as SyntheticImu makes them).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "wallar/dsp/imu/allan_variance.hpp"

namespace wallar::test {
namespace {

// White noise of density n plus a random walk of k, at rate_hz: the discrete forms the IMU
// simulator uses (n * sqrt(rate) per sample; k / sqrt(rate) per step of the walk).
std::vector<double> still_axis(double n, double k, double rate_hz, double seconds, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> x(static_cast<std::size_t>(seconds * rate_hz));
  double bias = 0.0;
  for (double& v : x) {
    v = bias + n * std::sqrt(rate_hz) * g(rng);
    bias += k / std::sqrt(rate_hz) * g(rng);
  }
  return x;
}

TEST(AllanVariance, WhiteNoiseFollowsItsClosedForm) {
  // White noise of density n: adev(tau) = n / sqrt(tau) at every tau.
  const auto x = still_axis(2e-4, 0.0, 200.0, 1000.0, 3);
  const auto curve = dsp::allan_deviation(x, 200.0);
  ASSERT_GT(curve.size(), 30u);
  EXPECT_DOUBLE_EQ(curve.front().tau_s, 1.0 / 200.0);
  EXPECT_NEAR(curve.back().tau_s, 100.0, 10.0);  // up to a tenth of the record
  for (const dsp::AllanPoint& p : curve) {
    if (p.tau_s > 1.0) break;  // beyond, fewer clusters: the estimate scatters by 10 % and more
    EXPECT_NEAR(p.adev * std::sqrt(p.tau_s), 2e-4, 0.06 * 2e-4) << p.tau_s;
  }
  const dsp::AllanNoise noise = dsp::allan_noise(curve);
  ASSERT_TRUE(noise.white_density);
  EXPECT_NEAR(*noise.white_density, 2e-4, 0.04 * 2e-4);
  EXPECT_FALSE(noise.random_walk);  // no +1/2 slope in this one
}

TEST(AllanVariance, TheNoiseDensityAndRandomWalkAreReadBackFromAStillStream) {
  // A gyro axis: 2e-4 rad/s/sqrt(Hz) white, 2e-4 rad/s^2/sqrt(Hz) walk (the lines cross at
  // 1.7 s), five minutes at 200 Hz, three seeds.
  for (unsigned seed = 1; seed <= 3; ++seed) {
    const auto x = still_axis(2e-4, 2e-4, 200.0, 300.0, seed);
    const dsp::AllanNoise noise = dsp::allan_noise(dsp::allan_deviation(x, 200.0));
    ASSERT_TRUE(noise.white_density) << seed;
    ASSERT_TRUE(noise.random_walk) << seed;
    EXPECT_NEAR(*noise.white_density, 2e-4, 0.05 * 2e-4) << seed;
    EXPECT_NEAR(*noise.random_walk, 2e-4, 0.35 * 2e-4) << seed;
    EXPECT_GT(noise.tau_min_s, 0.5);
    EXPECT_LT(noise.tau_min_s, 6.0);
  }
  // Too short a record for the walk to show: none claimed.
  const auto short_x = still_axis(2e-4, 2e-5, 200.0, 20.0, 9);
  EXPECT_FALSE(dsp::allan_noise(dsp::allan_deviation(short_x, 200.0)).random_walk);
  EXPECT_TRUE(dsp::allan_deviation(std::vector<double>(10, 0.0), 200.0).empty());
}

}  // namespace
}  // namespace wallar::test
