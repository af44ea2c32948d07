// SPDX-License-Identifier: Apache-2.0
/// @file device_clock.cpp
/// @brief Device sample clock to CLOCK_MONOTONIC: lower envelope of recent observations plus
/// the long-baseline slope.
#include "wallar/drivers/imu/device_clock.hpp"

#include <algorithm>

namespace wallar::drivers {
namespace {
// A slope over fewer samples than this is dominated by latency jitter: keep the nominal one.
constexpr std::uint64_t kMinBaseline = 16;
// Later than the model by this many periods: the device stalled or samples went missing.
constexpr double kGapPeriods = 10.0;
}  // namespace

DeviceClock::DeviceClock(DurationNs nominal_period_ns, double max_rate_error,
                         DurationNs fixed_latency_ns)
    : nominal_period_ns_(static_cast<double>(nominal_period_ns)),
      max_rate_error_(max_rate_error),
      fixed_latency_ns_(fixed_latency_ns),
      period_ns_(static_cast<double>(nominal_period_ns)) {}

void DeviceClock::reset() {
  period_ns_ = nominal_period_ns_;
  observations_ = 0;
  window_size_ = 0;
  window_next_ = 0;
}

void DeviceClock::restart(std::uint64_t k, double t) {
  k_anchor_ = k_first_ = k;
  t_anchor_ns_ = t_first_ns_ = t;
  window_size_ = 0;
  window_next_ = 0;
}

void DeviceClock::observe(std::uint64_t k, TimeNs t_obs_ns) {
  const double t = static_cast<double>(t_obs_ns - fixed_latency_ns_);
  if (observations_++ == 0) {
    restart(k, t);
  } else {
    const double late =
        t - (t_anchor_ns_ + (static_cast<double>(k) - static_cast<double>(k_anchor_)) * period_ns_);
    if (late > kGapPeriods * period_ns_) {
      ++gaps_;
      restart(k, t);  // the baseline before a stall says nothing about after it
    } else if (k > k_first_ + kMinBaseline) {
      const double slope = (t - t_first_ns_) / static_cast<double>(k - k_first_);
      period_ns_ = std::clamp(slope, nominal_period_ns_ * (1.0 - max_rate_error_),
                              nominal_period_ns_ * (1.0 + max_rate_error_));
    }
  }
  window_k_[window_next_] = k;
  window_t_ns_[window_next_] = t;
  window_next_ = (window_next_ + 1) % kWindow;
  window_size_ = std::min(window_size_ + 1, kWindow);
  // The lower envelope: the earliest time for sample k that a recent observation allows.
  // Carrying an observation forward by dk periods carries the period's error dk times; the
  // slope's error shrinks as 1 / baseline, so only observations within a quarter of the
  // baseline are carried (the carried error stays below a quarter of the latency jitter).
  const double max_dk = std::max(1.0, static_cast<double>(k - k_first_) / 4.0);
  double t_k = t;
  for (std::size_t i = 0; i < window_size_; ++i) {
    const double dk = static_cast<double>(k) - static_cast<double>(window_k_[i]);
    if (dk <= max_dk) t_k = std::min(t_k, window_t_ns_[i] + dk * period_ns_);
  }
  k_anchor_ = k;
  t_anchor_ns_ = t_k;
}

TimeNs DeviceClock::time_of(std::uint64_t k) const {
  const double dk = static_cast<double>(k) - static_cast<double>(k_anchor_);
  return static_cast<TimeNs>(t_anchor_ns_ + dk * period_ns_);
}

}  // namespace wallar::drivers
