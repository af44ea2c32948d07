// SPDX-License-Identifier: Apache-2.0
/// @file stereo_pairer.cpp
/// @brief Timestamp pairing of stereo frames.
#include "wallar/drivers/sync/stereo_pairer.hpp"

#include <cstdlib>

namespace wallar::sync {

StereoPairer::Result StereoPairer::push(int cam, CameraFrame frame) {
  Result result;
  const auto self = static_cast<std::size_t>(cam);
  const std::size_t other = 1 - self;

  // A newer frame of this camera replaces an older one still waiting: that one is lost.
  if (pending_[self]) {
    result.unpaired[self] = std::move(pending_[self]);
    ++stats_.unpaired[self];
    pending_[self].reset();
  }
  if (pending_[other]) {
    const DurationNs dt = frame.t_ns - pending_[other]->t_ns;
    if (std::llabs(dt) <= tolerance_ns_) {
      StereoFrame pair;
      pair.sequence = next_sequence_++;
      CameraFrame& mate = *pending_[other];
      pair.left = cam == 0 ? std::move(frame) : std::move(mate);
      pair.right = cam == 0 ? std::move(mate) : std::move(frame);
      pair.t_ns = pair.left.t_ns;
      pending_[other].reset();
      const DurationNs skew = std::llabs(pair.skew_ns());
      ++stats_.pairs;
      stats_.sum_abs_skew_ns += static_cast<double>(skew);
      if (skew > stats_.max_abs_skew_ns) stats_.max_abs_skew_ns = skew;
      result.pair = std::move(pair);
      return result;
    }
    if (dt > tolerance_ns_) {
      // The other camera's frame is too old to ever be paired: give up on it.
      result.unpaired[other] = std::move(pending_[other]);
      ++stats_.unpaired[other];
      pending_[other].reset();
    }
  }
  pending_[self] = std::move(frame);
  return result;
}

std::array<std::optional<CameraFrame>, 2> StereoPairer::flush() {
  std::array<std::optional<CameraFrame>, 2> out;
  for (std::size_t i = 0; i < 2; ++i) {
    if (pending_[i]) {
      ++stats_.unpaired[i];
      out[i] = std::move(pending_[i]);
      pending_[i].reset();
    }
  }
  return out;
}

SyncAssessment assess_sync(const PairingStats& stats, DurationNs tolerance_ns) {
  SyncAssessment a;
  a.frames = 2 * stats.pairs + stats.unpaired[0] + stats.unpaired[1];
  a.paired_percent =
      a.frames > 0 ? 100.0 * static_cast<double>(2 * stats.pairs) / static_cast<double>(a.frames)
                   : 0.0;
  a.mean_skew_ms = stats.mean_abs_skew_ns() * 1e-6;
  a.max_skew_ms = static_cast<double>(stats.max_abs_skew_ns) * 1e-6;
  a.tolerance_ms = static_cast<double>(tolerance_ns) * 1e-6;
  a.low_pairing = a.paired_percent < 90.0;
  a.high_skew =
      static_cast<double>(stats.max_abs_skew_ns) > 0.5 * static_cast<double>(tolerance_ns);
  return a;
}

}  // namespace wallar::sync
