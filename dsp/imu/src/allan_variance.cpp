// SPDX-License-Identifier: Apache-2.0
/// @file allan_variance.cpp
/// @brief Overlapping Allan deviation from the integrated signal, and the slope fits.
#include "wallar/dsp/imu/allan_variance.hpp"

#include <algorithm>
#include <cmath>

namespace wallar::dsp {

std::vector<AllanPoint> allan_deviation(std::span<const double> samples, double rate_hz,
                                        int per_decade) {
  std::vector<AllanPoint> out;
  const std::size_t n = samples.size();
  if (n < 20 || !(rate_hz > 0.0) || per_decade < 1) return out;
  const double dt = 1.0 / rate_hz;
  // theta_k: the integral of the signal up to sample k.
  std::vector<double> theta(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i) theta[i + 1] = theta[i] + samples[i] * dt;
  std::size_t last_m = 0;
  for (int j = 0;; ++j) {
    const auto m = static_cast<std::size_t>(std::floor(std::pow(10.0, j / double(per_decade))));
    if (m <= last_m) continue;
    if (m > n / 10) break;
    last_m = m;
    const double tau = static_cast<double>(m) * dt;
    double sum = 0.0;
    const std::size_t terms = n + 1 - 2 * m;
    for (std::size_t k = 0; k < terms; ++k) {
      const double d = theta[k + 2 * m] - 2.0 * theta[k + m] + theta[k];
      sum += d * d;
    }
    const double avar = sum / (2.0 * tau * tau * static_cast<double>(terms));
    out.push_back({tau, std::sqrt(avar)});
  }
  return out;
}

AllanNoise allan_noise(std::span<const AllanPoint> curve, double slope_tolerance) {
  AllanNoise r;
  if (curve.size() < 3) return r;
  const auto min_it =
      std::min_element(curve.begin(), curve.end(),
                       [](const AllanPoint& a, const AllanPoint& b) { return a.adev < b.adev; });
  const auto i_min = static_cast<std::size_t>(min_it - curve.begin());
  r.bias_instability = min_it->adev / 0.664;
  r.tau_min_s = min_it->tau_s;
  // Local slope at point i: from its neighbours.
  const auto slope = [&](std::size_t i) {
    const std::size_t a = i == 0 ? 0 : i - 1;
    const std::size_t b = std::min(i + 1, curve.size() - 1);
    return std::log(curve[b].adev / curve[a].adev) / std::log(curve[b].tau_s / curve[a].tau_s);
  };
  // White noise from the short taus only (a hundredth of the record and below: thousands of
  // clusters each), where the estimate scatters least.
  const double white_tau_max = curve.back().tau_s / 10.0;
  double white_sum = 0.0, walk_sum = 0.0;
  int white_n = 0, walk_n = 0;
  for (std::size_t i = 0; i < curve.size(); ++i) {
    const double s = slope(i);
    const double log_tau = std::log(curve[i].tau_s);
    const double log_adev = std::log(curve[i].adev);
    if (i < i_min && curve[i].tau_s <= white_tau_max && std::abs(s + 0.5) < slope_tolerance) {
      white_sum += log_adev + 0.5 * log_tau;  // the -1/2 line's value at tau = 1 s
      ++white_n;
    } else if (i > i_min && std::abs(s - 0.5) < slope_tolerance) {
      walk_sum += log_adev - 0.5 * (log_tau - std::log(3.0));  // +1/2 line at tau = 3 s
      ++walk_n;
    }
  }
  if (white_n >= 2) r.white_density = std::exp(white_sum / white_n);
  if (walk_n >= 2) r.random_walk = std::exp(walk_sum / walk_n);
  return r;
}

}  // namespace wallar::dsp
