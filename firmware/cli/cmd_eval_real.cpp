// SPDX-License-Identifier: Apache-2.0
/// @file cmd_eval_real.cpp
/// @brief `wallar eval real --recording DIR`: the room in a real recording, the floor against
/// IMU and ground-truth gravity, and an overlay figure (tools/eval/real.hpp). The map is the
/// appliance's (lock step over the whole recording), or with --map-source orb the study's own
/// sparse map from ORB matches of --pairs stereo pairs.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include "commands.hpp"
#include "study_map.hpp"
#include "wallar/core/error.hpp"
#include "wallar/eval/real.hpp"

namespace wallar::cli {
namespace {

struct EvalRealArgs {
  std::string recording;
  std::string out = "eval_out";
  std::string map_source = "appliance";
  int pairs = 8;
  bool pairs_given = false;
  double threshold_m = 0.05;
  std::uint64_t seed = 1;
  bool json = false;
};

// "12.34" or "n/a" for a json number that may be null.
std::string deg_text(const nlohmann::json& v) {
  if (v.is_null()) return "n/a";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v.get<double>());
  return buf;
}

std::string to_text(const nlohmann::json& d) {
  std::string text;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "wallar eval real: %s\nsparse map (%s): %zu points from %zu of %zu stereo pairs "
                "(%s), room search %.1f ms, %zu surfaces:\n",
                d["recording"].get<std::string>().c_str(),
                d["map_description"].get<std::string>().c_str(), d["points"].get<std::size_t>(),
                d["pairs_used"].get<std::size_t>(), d["pairs_in_recording"].get<std::size_t>(),
                d["gravity_aligned"].get<bool>() ? "gravity-aligned" : "3-D: IMU not at rest",
                d["room_time_ms"].get<double>(), d["surfaces"].size());
  text += buf;
  for (const auto& s : d["surfaces"]) {
    std::snprintf(buf, sizeof buf,
                  "  %-8s n = (%+.3f, %+.3f, %+.3f), d = %+.3f m, %u inliers, rmse %.4f m\n",
                  s["name"].get<std::string>().c_str(), s["normal"][0].get<double>(),
                  s["normal"][1].get<double>(), s["normal"][2].get<double>(), s["d"].get<double>(),
                  s["inliers"].get<unsigned>(), s["rmse_m"].get<double>());
    text += buf;
  }
  if (!d["ground_truth"].get<bool>()) text += "no ground truth in this recording\n";
  text +=
      "IMU gravity vs ground truth: " + deg_text(d["imu_gravity_vs_ground_truth_deg"]) + " deg\n";
  const auto& floor = d["floor"];
  if (floor.is_null()) {
    text += "floor: not found\n";
  } else {
    std::snprintf(buf, sizeof buf,
                  "floor %.3f m below the camera; its free 3-D fit is %s deg from IMU gravity, "
                  "%s deg from ground-truth gravity\n",
                  floor["distance_below_camera_m"].get<double>(),
                  deg_text(floor["free_fit_vs_imu_gravity_deg"]).c_str(),
                  deg_text(floor["free_fit_vs_ground_truth_gravity_deg"]).c_str());
    text += buf;
  }
  std::snprintf(buf, sizeof buf, "total %.0f ms\n", d["time_ms"].get<double>());
  text += buf;
  return text;
}

int run_eval_real_command(const EvalRealArgs& a) {
  // Checked before the output folder is made, so a typo leaves nothing behind.
  std::error_code ec;
  if (!std::filesystem::is_directory(a.recording, ec)) {
    throw_input_error(a.recording, 0, "no such recording folder");
  }
  if (a.pairs_given && a.map_source != "orb") {
    throw InputError(
        "--pairs chooses the stereo pairs of --map-source orb (the appliance's map "
        "takes every frame)");
  }
  eval::RealStudyOptions options;
  options.recording = a.recording;
  options.map_source =
      a.map_source == "orb" ? eval::RealMapSource::kOrb : eval::RealMapSource::kAppliance;
  options.appliance_map = appliance_map_for_study;
  options.pairs = a.pairs;
  options.threshold_m = a.threshold_m;
  options.seed = a.seed;
  eval::OutputDir out(a.out, false);
  const nlohmann::json summary = eval::run_real_study(options, out);
  if (a.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << to_text(summary) << "outputs in " << out.path().string() << "/\n";
  }
  return kExitOk;
}

}  // namespace

void add_eval_real_command(CLI::App& eval, std::function<int()>& run) {
  auto a = std::make_shared<EvalRealArgs>();
  CLI::App* cmd = eval.add_subcommand(
      "real", "The room in a real EuRoC recording: floor vs IMU and ground-truth gravity, overlay");
  cmd->add_option("--recording", a->recording,
                  "Recording: EuRoC folder (ROOT or ROOT/mav0) or .mcap file")
      ->required();
  cmd->add_option("--out", a->out, "Folder for real_overlay.png, real_map.csv, real_summary.json")
      ->capture_default_str();
  cmd->add_option("--map-source", a->map_source,
                  "appliance: the appliance's map over the whole recording (lock step); orb: a "
                  "sparse map from ORB matches of --pairs stereo pairs")
      ->check(CLI::IsMember({"appliance", "orb"}))
      ->capture_default_str();
  cmd->add_option("--pairs", a->pairs,
                  "--map-source orb: stereo pairs for the sparse map, spread over the recording")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str()
      ->each([a](const std::string&) { a->pairs_given = true; });
  cmd->add_option("--threshold-m", a->threshold_m, "Inlier threshold [m]")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--seed", a->seed, "Random seed of the room search")->capture_default_str();
  cmd->add_flag("--json", a->json, "Print the summary as JSON on stdout");
  cmd->callback([a, &run] { run = [a] { return run_eval_real_command(*a); }; });
}

}  // namespace wallar::cli
