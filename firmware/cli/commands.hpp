// SPDX-License-Identifier: Apache-2.0
/// @file commands.hpp
/// @brief The wallar subcommands: each registers its options and returns an exit code.
///
/// Threading: called from main() only.
#pragma once

#include <CLI/CLI.hpp>
#include <atomic>
#include <functional>
#include <utility>

namespace wallar::cli {

/// Exit codes, documented in README.md.
enum ExitCode : int {
  kExitOk = 0,
  kExitFailure = 1,   //!< a runtime failure (device, I/O)
  kExitUsage = 2,     //!< bad command line or bad input file: the user's to fix
  kExitBadInput = 2,  //!< a bad input file (recording, board, calibration, cloud)
  kExitInterrupted = 130,
};

/// Set by SIGINT/SIGTERM; long-running commands poll it and stop cleanly.
std::atomic<bool>& stop_requested();
/// The signal that set stop_requested() (SIGINT or SIGTERM), 0 before one arrived.
std::atomic<int>& stop_signal();
/// Set by SIGUSR1: print the statistics now (wallar run).
std::atomic<bool>& stats_requested();

/// Each adds a subcommand to `app` and sets `run` to its action when it is chosen.
void add_run_command(CLI::App& app, std::function<int()>& run);
void add_replay_command(CLI::App& app, std::function<int()>& run);
void add_record_command(CLI::App& app, std::function<int()>& run);
void add_bench_command(CLI::App& app, std::function<int()>& run);
void add_walls_command(CLI::App& app, std::function<int()>& run);
void add_eval_command(CLI::App& app, std::function<int()>& run);
void add_imu_command(CLI::App& app, std::function<int()>& run);
void add_track_command(CLI::App& app, std::function<int()>& run);
void add_render_command(CLI::App& app, std::function<int()>& run);
void add_calibrate_command(CLI::App& app, std::function<int()>& run);
void add_convert_command(CLI::App& app, std::function<int()>& run);
void add_calibrate_stereo_commands(CLI::App& calibrate, std::function<int()>& run);
/// `wallar eval real`, added to the `eval` subcommand.
void add_eval_real_command(CLI::App& eval, std::function<int()>& run);
/// `wallar eval marker`, added to the `eval` subcommand.
void add_eval_marker_command(CLI::App& eval, std::function<int()>& run);
/// `wallar eval synth-rig`, added to the `eval` subcommand.
void add_eval_synth_rig_command(CLI::App& eval, std::function<int()>& run);

}  // namespace wallar::cli

#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"

namespace wallar::cli {

/// A recording for a command: a EuRoC folder or an MCAP file (recording::read_recording). What
/// the reader could not use (an MCAP file cut off by power loss) is said on stderr, one line.
recording::EurocRecording read_recording_reporting(const std::string& path,
                                                   const recording::ReadOptions& options = {});

/// Playback flags shared by the commands that play a recording.
struct ReplayFlags {
  double rate = -1.0;  //!< < 0: not given on the command line
  bool fast = false;
  double start_s = -1.0;
  int skip = -1;
  double tolerance_ms = -1.0;

  /// The options, starting from `base` (e.g. the board's) and overridden by the flags given.
  [[nodiscard]] source::ReplayOptions apply(source::ReplayOptions base) const;
};
void add_replay_flags(CLI::App& cmd, ReplayFlags& flags);

/// The wall search's scores by their command-line names: ransac, msac, bsf (BSF-RANSAC),
/// binomial (B-RANSAC) or contrast (BSF on the band's contrast, for clouds whose noise is well
/// within the threshold). One table; options check the name with kScoreMethodNames.
inline constexpr std::pair<const char*, dsp::ScoreMethod> kScoreMethods[] = {
    {"ransac", dsp::ScoreMethod::kRansac},
    {"msac", dsp::ScoreMethod::kMsac},
    {"bsf", dsp::ScoreMethod::kBsf},
    {"binomial", dsp::ScoreMethod::kBinomial},
    {"contrast", dsp::ScoreMethod::kContrast}};
inline const std::vector<std::string> kScoreMethodNames = [] {
  std::vector<std::string> names;
  for (const auto& [name, method] : kScoreMethods) names.emplace_back(name);
  return names;
}();
/// The score named `m` (a name kScoreMethodNames holds; any other gives B-RANSAC).
inline dsp::ScoreMethod score_method_named(const std::string& m) {
  for (const auto& [name, method] : kScoreMethods) {
    if (m == name) return method;
  }
  return dsp::ScoreMethod::kBinomial;
}
/// The command-line name of a score method (the inverse of score_method_named).
inline const char* score_method_name(dsp::ScoreMethod m) {
  for (const auto& [name, method] : kScoreMethods) {
    if (m == method) return name;
  }
  return "?";
}

}  // namespace wallar::cli
