// SPDX-License-Identifier: Apache-2.0
/// @file cmd_replay.cpp
/// @brief `wallar replay RECORDING`: play a recording, report what it holds and how it played.
#include <cstdio>
#include <iostream>

#include "commands.hpp"
#include "wallar/drivers/recording/stream_stats.hpp"
#include "wallar/firmware/report.hpp"
#include "wallar/firmware/source_runner.hpp"

namespace wallar::cli {
namespace {

struct ReplayArgs {
  std::string recording;
  bool stats = false;
  bool json = false;
  bool no_images = false;
  bool strict = false;
  ReplayFlags flags;
};

// Counts what arrives, as any consumer would see it.
class CountingSink final : public source::SensorSink {
 public:
  void on_imu(const ImuSample& /*sample*/) override {}
  void on_stereo(const StereoFrame& /*frame*/) override {}
  void on_unpaired(int cam, const CameraFrame& frame) override {
    std::fprintf(stderr, "wallar: warning: cam%d frame %lld has no partner within tolerance\n", cam,
                 static_cast<long long>(frame.t_ns));
  }
};

int run_replay_command(const ReplayArgs& args) {
  const recording::EurocRecording rec = read_recording_reporting(args.recording);
  source::ReplayOptions options = args.flags.apply({});
  options.with_images = !args.no_images;
  if (args.strict) {
    recording::check_stereo_pairs(rec, source::ReplaySource(rec, options).pair_tolerance_ns());
  }
  CountingSink sink;
  const source::ReplayStats played = firmware::run_replay(rec, options, sink, stop_requested());

  if (args.json) {
    nlohmann::json out = {{"recording", args.recording}, {"replay", firmware::to_json(played)}};
    if (args.stats) out["streams"] = firmware::to_json(recording::recording_stats(rec));
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << "recording " << args.recording << "\n";
    if (args.stats) std::cout << firmware::to_text(recording::recording_stats(rec));
    std::cout << firmware::to_text(played);
  }
  return played.stopped ? kExitInterrupted : kExitOk;
}

}  // namespace

void add_replay_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* cmd =
      app.add_subcommand("replay", "Play a recording (EuRoC folder or MCAP) as if live");
  cmd->add_option("recording", args->recording,
                  "Recording: a folder holding mav0/, or a .mcap file")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_flag("--stats", args->stats, "Print counts, rates, gaps and pairing of every stream");
  cmd->add_flag("--json", args->json, "Print the report as JSON on stdout");
  cmd->add_flag("--no-images", args->no_images, "Do not decode images (timing only)");
  cmd->add_flag("--strict", args->strict,
                "Fail on the first frame without a stereo partner instead of counting it");
  add_replay_flags(*cmd, args->flags);
  cmd->callback([args, &run] { run = [args] { return run_replay_command(*args); }; });
}

}  // namespace wallar::cli
