// SPDX-License-Identifier: Apache-2.0
/// @file cmd_convert.cpp
/// @brief `wallar convert IN OUT`: a recording from the EuRoC layout to one MCAP file or back,
/// and the recording reader every command shares.
#include <iostream>

#include "commands.hpp"
#include "wallar/core/error.hpp"

namespace wallar::cli {

recording::EurocRecording read_recording_reporting(const std::string& path,
                                                   const recording::ReadOptions& options) {
  recording::EurocRecording rec = recording::read_recording(path, options);
  if (!rec.read_note.empty()) std::cerr << "wallar: warning: " << rec.read_note << "\n";
  return rec;
}

namespace {

struct ConvertArgs {
  std::string in;
  std::string out;
  std::string compression = "zstd";
  bool json = false;
};

int run_convert(const ConvertArgs& a) {
  const bool to_mcap = !recording::is_mcap_recording(a.in);
  if (to_mcap && std::filesystem::path(a.out).extension() != ".mcap") {
    throw InputError("wallar convert: " + a.out +
                     ": a EuRoC folder converts to an MCAP file; name it NAME.mcap");
  }
  const recording::EurocRecording rec = read_recording_reporting(a.in);
  recording::McapRecordingOptions options;
  options.compression = recording::mcap::parse_compression(a.compression, "--compression");
  const recording::ConvertCounts c = recording::convert_recording(rec, a.out, to_mcap, options);
  const nlohmann::json report = {{"in", a.in},
                                 {"out", a.out},
                                 {"format", to_mcap ? "mcap" : "euroc"},
                                 {"frames", {c.frames[0], c.frames[1]}},
                                 {"imu", c.imu},
                                 {"ground_truth", c.ground_truth},
                                 {"bytes_written", c.bytes_written},
                                 {"complete_input", rec.read_note.empty()}};
  if (a.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << "converted " << a.in << " -> " << a.out << " (" << (to_mcap ? "MCAP" : "EuRoC")
              << "): " << c.frames[0] << " + " << c.frames[1] << " frames, " << c.imu
              << " IMU samples, " << c.ground_truth << " ground-truth rows, " << c.bytes_written
              << " bytes\n";
  }
  return kExitOk;
}

}  // namespace

void add_convert_command(CLI::App& app, std::function<int()>& run) {
  auto a = std::make_shared<ConvertArgs>();
  CLI::App* cmd = app.add_subcommand(
      "convert", "Convert a recording between the EuRoC layout and one MCAP file (either way)");
  cmd->add_option("in", a->in, "A EuRoC folder (ROOT or ROOT/mav0) or an .mcap file")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("out", a->out, "OUT.mcap (from a folder) or a new folder (from an .mcap)")
      ->required();
  cmd->add_option("--compression", a->compression, "MCAP chunk compression: zstd, lz4 or none")
      ->capture_default_str()
      ->check(CLI::IsMember({"zstd", "lz4", "none"}));
  cmd->add_flag("--json", a->json, "Print the report as JSON on stdout");
  cmd->callback([a, &run] { run = [a] { return run_convert(*a); }; });
}

}  // namespace wallar::cli
