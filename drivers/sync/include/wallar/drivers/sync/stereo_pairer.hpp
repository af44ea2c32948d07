// SPDX-License-Identifier: Apache-2.0
/// @file stereo_pairer.hpp
/// @brief Pairs left and right camera frames by timestamp within a tolerance.
///
/// Frames of each camera arrive in time order (live capture or replay). A left and a right
/// frame whose times differ by at most the tolerance form a pair; a frame that can no longer
/// find a partner (the other camera has moved past it) is counted as unpaired and handed to the
/// caller, never dropped silently. Holds at most one pending frame per camera: no allocation.
///
/// Threading: single-threaded; the owner serialises push() calls.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "wallar/core/stereo_frame.hpp"

namespace wallar::sync {

struct PairingStats {
  std::uint64_t pairs = 0;
  std::array<std::uint64_t, 2> unpaired{0, 0};  //!< frames of cam0/cam1 that found no partner
  DurationNs max_abs_skew_ns = 0;               //!< largest |t_right - t_left| of a pair
  double sum_abs_skew_ns = 0.0;

  [[nodiscard]] double mean_abs_skew_ns() const {
    return pairs ? sum_abs_skew_ns / static_cast<double>(pairs) : 0.0;
  }
};

/// How well a stereo pair is synchronised, from its pairing statistics over a window (the
/// first seconds of a live run): what a rig of two free-running cameras (no trigger) is told at
/// start, since it triangulates images taken up to max skew apart.
struct SyncAssessment {
  std::uint64_t frames = 0;     //!< frames both cameras delivered in the window
  double paired_percent = 0.0;  //!< of those, in a pair
  double mean_skew_ms = 0.0;    //!< |t_right - t_left| over the pairs
  double max_skew_ms = 0.0;
  double tolerance_ms = 0.0;
  bool low_pairing = false;  //!< under 90 % paired
  bool high_skew = false;    //!< max skew above half the tolerance
  [[nodiscard]] bool warn() const { return low_pairing || high_skew; }
};
/// `stats` counted since the cameras started; `tolerance_ns` the pairer's.
SyncAssessment assess_sync(const PairingStats& stats, DurationNs tolerance_ns);

class StereoPairer {
 public:
  /// tolerance_ns: largest |t_left - t_right| accepted; half the frame period is a good choice.
  explicit StereoPairer(DurationNs tolerance_ns) : tolerance_ns_(tolerance_ns) {}

  struct Result {
    std::optional<StereoFrame> pair;
    /// Frames given up on in this call, indexed by camera.
    std::array<std::optional<CameraFrame>, 2> unpaired;
  };

  /// Offers a frame of camera `cam` (0 = left, 1 = right). At most one pair, and at most one
  /// given-up frame per camera, come out of one call.
  Result push(int cam, CameraFrame frame);
  /// Gives up on whatever is still pending (end of stream); returns them as unpaired.
  std::array<std::optional<CameraFrame>, 2> flush();

  [[nodiscard]] const PairingStats& stats() const { return stats_; }
  [[nodiscard]] DurationNs tolerance_ns() const { return tolerance_ns_; }

 private:
  DurationNs tolerance_ns_;
  std::array<std::optional<CameraFrame>, 2> pending_;
  std::uint64_t next_sequence_ = 0;
  PairingStats stats_;
};

}  // namespace wallar::sync
