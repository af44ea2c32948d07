// SPDX-License-Identifier: Apache-2.0
/// @file allan_variance.hpp
/// @brief The overlapping Allan deviation of a still IMU's gyro or accelerometer axis, and the
/// noise terms read from its slopes (IEEE Std 952, annex C): white noise (the density a filter
/// or Kalibr's imu.yaml calls *_noise_density) on the -1/2 slope, read at tau = 1 s; random
/// walk (*_random_walk) on the +1/2 slope, read at tau = 3 s; the bias instability at the
/// curve's floor.
///
/// A recording that is too short for the +1/2 slope to appear (it needs some ten times the
/// tau where the two lines cross: a MEMS gyro's ~10-20 s) gives no random walk: the result
/// says so instead of fitting noise.
///
/// Threading: pure functions; they allocate their result.
#pragma once

#include <optional>
#include <span>
#include <vector>

namespace wallar::dsp {

struct AllanPoint {
  double tau_s = 0.0;
  double adev = 0.0;  //!< Allan deviation, in the samples' unit
};

/// The overlapping Allan deviation of a signal sampled at rate_hz, at cluster sizes spaced
/// `per_decade` to the decade from one sample up to a tenth of the record (fewer clusters
/// than that average too few differences to mean anything).
std::vector<AllanPoint> allan_deviation(std::span<const double> samples, double rate_hz,
                                        int per_decade = 10);

struct AllanNoise {
  /// White noise density [unit * sqrt(s)] = [unit / sqrt(Hz)]: the -1/2 line at tau = 1 s.
  std::optional<double> white_density;
  /// Random walk [unit / sqrt(s)]: the +1/2 line at tau = 3 s; none when the curve never
  /// turns up along a +1/2 slope.
  std::optional<double> random_walk;
  double bias_instability = 0.0;  //!< the curve's minimum / 0.664 [unit]
  double tau_min_s = 0.0;         //!< where the minimum is
};

/// Reads the noise terms from the slopes: the points whose local log-log slope is within
/// `slope_tolerance` of -1/2 (before the minimum, and at taus up to a hundredth of the
/// record, where the estimate scatters least) and of +1/2 (after the minimum).
AllanNoise allan_noise(std::span<const AllanPoint> curve, double slope_tolerance = 0.15);

}  // namespace wallar::dsp
