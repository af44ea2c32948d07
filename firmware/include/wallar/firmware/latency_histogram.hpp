// SPDX-License-Identifier: Apache-2.0
/// @file latency_histogram.hpp
/// @brief A fixed-size log-linear latency histogram (HdrHistogram-like) that a fixed-rate
/// thread records into in O(1) without allocating, and any thread reads percentiles from.
///
/// Bins: one for values below 1024 ns (~1 us), then 32 equal sub-bins per power of two from
/// 2^10 ns up to 2^36 ns (~68.7 s), then one for everything above. A percentile is reported as
/// the upper edge of its bin (never above the largest recorded value), so it is never below
/// the true value and at most 1/32 (3.2 %) above it for values from 1 us to 68 s.
///
/// Threading: record() from one thread (several recorders also work: every update is an
/// atomic read-modify-write); count(), max_ns(), mean_ns(), percentile_ns() and summary() from
/// any thread at any time (while recording goes on they see a consistent-enough snapshot:
/// each bin is exact, the bins may be a few samples apart). reset() must not run concurrently
/// with record(). Nothing allocates.
#pragma once

#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "wallar/core/time.hpp"

namespace wallar::firmware {

struct LatencySummary {
  std::uint64_t count = 0;
  double p50_ms = 0.0;
  double p99_ms = 0.0;
  double max_ms = 0.0;
  double mean_ms = 0.0;
};

class LatencyHistogram {
 public:
  static constexpr int kSubBits = 5;  //!< 32 sub-bins per power of two
  static constexpr int kMinExp = 10;  //!< first octave starts at 2^10 ns
  static constexpr int kTopExp = 36;  //!< last octave ends at 2^36 ns (~68.7 s)
  static constexpr DurationNs kMinNs = DurationNs{1} << kMinExp;
  static constexpr DurationNs kTopNs = DurationNs{1} << kTopExp;
  /// Recorded values are clamped to [0, kMaxValueNs] (2^50 ns, ~13 days), so the sum cannot
  /// overflow in practice.
  static constexpr DurationNs kMaxValueNs = DurationNs{1} << 50;
  static constexpr std::size_t kSub = std::size_t{1} << kSubBits;
  static constexpr std::size_t kBins = 1 + static_cast<std::size_t>(kTopExp - kMinExp) * kSub + 1;

  /// The bin holding `ns` (already clamped to [0, kMaxValueNs]).
  static constexpr std::size_t bin_of(DurationNs ns) {
    if (ns < kMinNs) return 0;
    if (ns >= kTopNs) return kBins - 1;
    const auto v = static_cast<std::uint64_t>(ns);
    const int exp = std::bit_width(v) - 1;  // kMinExp .. kTopExp - 1
    const auto sub = static_cast<std::size_t>(v >> (exp - kSubBits)) & (kSub - 1);
    return 1 + static_cast<std::size_t>(exp - kMinExp) * kSub + sub;
  }

  /// The largest value bin `bin` holds (kMaxValueNs for the overflow bin).
  static constexpr DurationNs bin_upper_ns(std::size_t bin) {
    if (bin == 0) return kMinNs - 1;
    if (bin >= kBins - 1) return kMaxValueNs;
    const int exp = kMinExp + static_cast<int>((bin - 1) / kSub);
    const auto sub = static_cast<DurationNs>((bin - 1) % kSub);
    const DurationNs width = DurationNs{1} << (exp - kSubBits);
    return (DurationNs{1} << exp) + (sub + 1) * width - 1;
  }

  /// Adds one value; negative values count as 0, values above kMaxValueNs as kMaxValueNs.
  void record(DurationNs ns) noexcept {
    if (ns < 0) ns = 0;
    if (ns > kMaxValueNs) ns = kMaxValueNs;
    bins_[bin_of(ns)].fetch_add(1, std::memory_order_relaxed);
    count_.fetch_add(1, std::memory_order_relaxed);
    sum_ns_.fetch_add(static_cast<std::uint64_t>(ns), std::memory_order_relaxed);
    DurationNs seen = max_ns_.load(std::memory_order_relaxed);
    while (ns > seen && !max_ns_.compare_exchange_weak(seen, ns, std::memory_order_relaxed)) {
    }
  }

  [[nodiscard]] std::uint64_t count() const { return count_.load(std::memory_order_relaxed); }
  /// The largest recorded value (0 when empty).
  [[nodiscard]] DurationNs max_ns() const { return max_ns_.load(std::memory_order_relaxed); }
  /// The mean of the recorded values (0 when empty).
  [[nodiscard]] double mean_ns() const {
    const std::uint64_t n = count();
    if (n == 0) return 0.0;
    return static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / static_cast<double>(n);
  }

  /// The q-quantile (q in [0, 1], clamped): the upper edge of the bin holding the
  /// ceil(q * count)-th smallest value (the smallest for q = 0), capped at max_ns(); 0 when
  /// empty.
  [[nodiscard]] DurationNs percentile_ns(double q) const {
    std::uint64_t total = 0;
    for (const auto& bin : bins_) total += bin.load(std::memory_order_relaxed);
    if (total == 0) return 0;
    if (!(q > 0.0)) q = 0.0;  // also NaN
    if (q > 1.0) q = 1.0;
    auto rank = static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(total)));
    if (rank < 1) rank = 1;
    if (rank > total) rank = total;
    const DurationNs max = max_ns();
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBins; ++i) {
      seen += bins_[i].load(std::memory_order_relaxed);
      if (seen >= rank) {
        const DurationNs upper = bin_upper_ns(i);
        return upper < max ? upper : max;
      }
    }
    return max;  // not reached: bins only grow between the two passes
  }

  /// Count, median, 99th percentile, max and mean, in milliseconds.
  [[nodiscard]] LatencySummary summary() const {
    constexpr double kMsPerNs = 1e-6;
    LatencySummary s;
    s.count = count();
    s.p50_ms = static_cast<double>(percentile_ns(0.5)) * kMsPerNs;
    s.p99_ms = static_cast<double>(percentile_ns(0.99)) * kMsPerNs;
    s.max_ms = static_cast<double>(max_ns()) * kMsPerNs;
    s.mean_ms = mean_ns() * kMsPerNs;
    return s;
  }

  /// Forgets everything. Not concurrently with record().
  void reset() noexcept {
    for (auto& bin : bins_) bin.store(0, std::memory_order_relaxed);
    count_.store(0, std::memory_order_relaxed);
    sum_ns_.store(0, std::memory_order_relaxed);
    max_ns_.store(0, std::memory_order_relaxed);
  }

 private:
  std::array<std::atomic<std::uint64_t>, kBins> bins_{};
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::uint64_t> sum_ns_{0};
  std::atomic<DurationNs> max_ns_{0};
};

}  // namespace wallar::firmware
