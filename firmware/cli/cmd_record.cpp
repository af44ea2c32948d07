// SPDX-License-Identifier: Apache-2.0
/// @file cmd_record.cpp
/// @brief `wallar record`: write the board's sensor streams as an EuRoC recording.
#include <cstdio>
#include <iostream>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/source/recorder_sink.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/report.hpp"
#include "wallar/firmware/source_runner.hpp"

namespace wallar::cli {
namespace {

struct RecordArgs {
  std::string board;
  std::string from;
  std::string out;
  double duration_s = 0.0;
  bool json = false;
  ReplayFlags flags;
};

int run_record_command(const RecordArgs& args) {
  const firmware::BoardConfig board = firmware::load_board(args.board);
  std::filesystem::path source_path = args.from;
  source::ReplayOptions options;
  if (source_path.empty()) {
    if (board.source != firmware::BoardConfig::Source::kReplay) {
      std::fprintf(stderr,
                   "wallar: error: %s: live capture needs the camera and IMU drivers, which this "
                   "build does not have yet; record from a recording with --from\n",
                   args.board.c_str());
      return kExitFailure;
    }
    source_path = board.replay.recording;
    options.rate = board.replay.rate;
    options.start_offset_ns = s_to_ns(board.replay.start_offset_s);
    options.skip = board.replay.skip;
  }
  options = args.flags.apply(options);
  const recording::EurocRecording rec = recording::read_euroc(source_path);

  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::path(args.out) / "mav0", ec)) {
    throw_input_error(args.out, 0, "already holds a recording (mav0/); refusing to overwrite it");
  }
  recording::EurocWriter writer(args.out, rec.rig());
  source::RecorderSink sink(writer);
  const source::ReplayStats stats =
      firmware::run_replay(rec, options, sink, stop_requested(), s_to_ns(args.duration_s));
  writer.close();
  if (args.json) {
    std::cout << nlohmann::json{{"out", args.out},
                                {"imu_rows", writer.imu_written()},
                                {"cam_rows", {writer.frames_written(0), writer.frames_written(1)}},
                                {"replay", firmware::to_json(stats)}}
                     .dump(2)
              << "\n";
  } else {
    std::cout << "recorded " << writer.imu_written() << " IMU rows, " << writer.frames_written(0)
              << " + " << writer.frames_written(1) << " frames to " << args.out << "\n"
              << firmware::to_text(stats);
  }
  return kExitOk;
}

}  // namespace

void add_record_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<RecordArgs>();
  CLI::App* cmd = app.add_subcommand("record", "Record the sensor streams in the EuRoC layout");
  cmd->add_option("--board", args->board, "Board file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "Folder to write the recording to")->required();
  cmd->add_option("--from", args->from, "Record from this recording instead of live sensors")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--duration-s", args->duration_s, "Stop after this many seconds (0 = no limit)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--json", args->json, "Print the report as JSON on stdout");
  add_replay_flags(*cmd, args->flags);
  cmd->callback([args, &run] { run = [args] { return run_record_command(*args); }; });
}

}  // namespace wallar::cli
