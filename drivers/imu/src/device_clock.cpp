// SPDX-License-Identifier: Apache-2.0
/// @file device_clock.cpp
/// @brief Device sample clock to CLOCK_MONOTONIC: lower envelope plus long-baseline slope.
#include "wallar/drivers/imu/device_clock.hpp"

#include <algorithm>

namespace wallar::drivers {
namespace {
// Later-than-model observations pull the anchor up by this fraction of the difference: slow
// enough to ignore latency jitter, fast enough to follow a temperature drift.
constexpr double kCreep = 0.01;
// A period estimate needs this many samples of baseline before it replaces the nominal one.
constexpr std::uint64_t kMinBaseline = 50;
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
}

void DeviceClock::observe(std::uint64_t k, TimeNs t_obs_ns) {
  const double t = static_cast<double>(t_obs_ns - fixed_latency_ns_);
  if (observations_ == 0) {
    k_anchor_ = k_first_ = k;
    t_anchor_ns_ = t_first_ns_ = t;
    observations_ = 1;
    return;
  }
  ++observations_;
  if (k > k_first_ + kMinBaseline) {
    const double slope = (t - t_first_ns_) / static_cast<double>(k - k_first_);
    period_ns_ = std::clamp(slope, nominal_period_ns_ * (1.0 - max_rate_error_),
                            nominal_period_ns_ * (1.0 + max_rate_error_));
  }
  const double predicted =
      t_anchor_ns_ + (static_cast<double>(k) - static_cast<double>(k_anchor_)) * period_ns_;
  const double late = t - predicted;
  if (late > kGapPeriods * period_ns_) {
    ++gaps_;
    k_anchor_ = k_first_ = k;  // the baseline before a stall says nothing about after it
    t_anchor_ns_ = t_first_ns_ = t;
    return;
  }
  k_anchor_ = k;
  t_anchor_ns_ = late < 0.0 ? t : predicted + kCreep * late;
}

TimeNs DeviceClock::time_of(std::uint64_t k) const {
  const double dk = static_cast<double>(k) - static_cast<double>(k_anchor_);
  return static_cast<TimeNs>(t_anchor_ns_ + dk * period_ns_);
}

}  // namespace wallar::drivers
