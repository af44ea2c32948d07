// SPDX-License-Identifier: Apache-2.0
/// @file device_clock.hpp
/// @brief The one place where a device's sample clock is mapped to CLOCK_MONOTONIC.
///
/// An IMU samples on its own oscillator (nominal period, a few percent off and drifting with
/// temperature). The host sees each sample only later: at a data-ready edge (kernel
/// timestamp, latency of microseconds) or when its bytes arrive on a serial line (latency of
/// the transmission and the device's processing). The model is
///
///     t_ns(k) = t_anchor_ns + (k - k_anchor) * period_ns
///
/// for the sample with running index k. Observation latency is never negative, so the model
/// follows the lower envelope of the observations: at each observation the anchor is the
/// earliest time that any of the last kWindow observations, carried forward by the period,
/// allows (as in convex-hull clock sync; only observations within a quarter of the baseline
/// are carried, so the period's error is not multiplied into the stamp). Latency jitter therefore
/// never moves a stamp later, and a model that ran early or late is corrected within kWindow
/// observations. The period is the slope over the longest baseline since the last reset or gap,
/// bounded to the nominal period +- max_rate_error.
///
/// Threading: owned by one driver, single thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "wallar/core/time.hpp"

namespace wallar::drivers {

class DeviceClock {
 public:
  /// nominal_period_ns: the configured sample period; max_rate_error: the oscillator's
  /// tolerance as a fraction (0.05 = +-5 %); fixed_latency_ns: a known constant latency
  /// subtracted from every observation (serial transmission, on-chip filter delay).
  explicit DeviceClock(DurationNs nominal_period_ns, double max_rate_error = 0.05,
                       DurationNs fixed_latency_ns = 0);

  /// Forgets everything (device reset: the sample counter restarts).
  void reset();
  /// The sample with index k was observed at t_obs_ns (monotonic).
  void observe(std::uint64_t k, TimeNs t_obs_ns);
  [[nodiscard]] bool valid() const { return observations_ > 0; }
  /// Sample time of index k (valid() must be true).
  [[nodiscard]] TimeNs time_of(std::uint64_t k) const;
  /// Current period estimate [ns].
  [[nodiscard]] double period_ns() const { return period_ns_; }
  /// Observations that were later than the model by more than 10 periods: a gap (missed
  /// samples or a stall); the model is re-anchored there.
  [[nodiscard]] std::uint64_t gaps() const { return gaps_; }

 private:
  static constexpr std::size_t kWindow = 32;  //!< observations in the lower envelope

  void restart(std::uint64_t k, double t);

  double nominal_period_ns_;
  double max_rate_error_;
  DurationNs fixed_latency_ns_;
  double period_ns_;
  std::uint64_t k_anchor_ = 0;
  double t_anchor_ns_ = 0.0;
  std::uint64_t k_first_ = 0;
  double t_first_ns_ = 0.0;
  std::array<std::uint64_t, kWindow> window_k_{};
  std::array<double, kWindow> window_t_ns_{};
  std::size_t window_size_ = 0;
  std::size_t window_next_ = 0;
  std::uint64_t observations_ = 0;
  std::uint64_t gaps_ = 0;
};

}  // namespace wallar::drivers
