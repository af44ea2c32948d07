// SPDX-License-Identifier: Apache-2.0
/// @file replay_flags.cpp
/// @brief Playback options shared by run, replay and record.
#include "commands.hpp"

namespace wallar::cli {

void add_replay_flags(CLI::App& cmd, ReplayFlags& f) {
  cmd.add_option("--rate", f.rate, "Playback speed: 1 = real time, 2 = twice as fast, 0 = fast")
      ->check(CLI::NonNegativeNumber);
  cmd.add_flag("--fast", f.fast, "Play as fast as possible (same as --rate 0)");
  cmd.add_option("--start-s", f.start_s, "Skip this many seconds of the recording's start")
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--skip", f.skip, "After each stereo pair played, skip N pairs")
      ->check(CLI::Range(0, 1000));
  cmd.add_option("--tolerance-ms", f.tolerance_ms,
                 "Stereo pairing tolerance (default: half the frame period)")
      ->check(CLI::NonNegativeNumber);
}

source::ReplayOptions ReplayFlags::apply(source::ReplayOptions base) const {
  if (rate >= 0.0) base.rate = rate;
  if (fast) base.rate = 0.0;
  if (start_s >= 0.0) base.start_offset_ns = s_to_ns(start_s);
  if (skip >= 0) base.skip = static_cast<std::uint32_t>(skip);
  if (tolerance_ms >= 0.0) base.pair_tolerance_ns = static_cast<DurationNs>(tolerance_ms * 1e6);
  return base;
}

}  // namespace wallar::cli
