// SPDX-License-Identifier: Apache-2.0
/// @file cmd_eval.cpp
/// @brief `wallar eval ...`: the evaluation suite (tools/eval). Each experiment is its own
/// subcommand; `wallar eval all` runs every one of them into one folder.
#include <chrono>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "study_map.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/eval/experiments.hpp"
#include "wallar/eval/marker.hpp"
#include "wallar/eval/output.hpp"
#include "wallar/eval/real.hpp"

namespace wallar::cli {
namespace {

// The §4.1 scene's flags, shared by `synth` and `sweep`.
// `sweep` varies windows and clutter as grids, so it leaves out those two (with_extras false).
void add_scene_flags(CLI::App& cmd, dsp::ThesisSceneParams& p, bool with_extras) {
  cmd.add_option("--wall-points", p.wall_points, "Points on the 4 x 4 m wall")
      ->capture_default_str();
  cmd.add_option("--plane-points", p.plane_points, "Points on the plane in front of the wall")
      ->capture_default_str();
  cmd.add_option("--outliers", p.outliers, "Uniform outliers in front of the wall")
      ->capture_default_str();
  cmd.add_option("--noise-m", p.noise_m, "Uniform noise across each plane (full width) [m]")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  cmd.add_option("--wall-distance-m", p.wall_distance_m, "Wall distance [m]")
      ->capture_default_str()
      ->check(CLI::Range(0.2, 100.0));
  cmd.add_option("--plane-distance-m", p.plane_distance_m, "Front plane distance [m]")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 100.0));
  cmd.add_option("--wall-size-m", p.wall_size_m, "Wall side [m]")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 100.0));
  cmd.add_option("--plane-size-m", p.plane_size_m, "Front plane side [m]")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  if (!with_extras) return;
  cmd.add_option("--window-points", p.window_points, "Points seen through a window in the wall")
      ->capture_default_str();
  cmd.add_option("--clutter-points", p.clutter_points, "Points on boxes in front of the wall")
      ->capture_default_str();
}

struct SynthArgs {
  dsp::ThesisSceneParams scene;
  std::string out;
  bool json = false;
};

int run_synth(const SynthArgs& a) {
  if (a.scene.plane_distance_m >= a.scene.wall_distance_m) {
    throw CLI::ValidationError("--plane-distance-m", "must be less than --wall-distance-m");
  }
  const dsp::LabelledCloud scene = dsp::make_thesis_scene(a.scene);
  eval::write_labelled_scene(scene, a.out);
  std::array<std::size_t, 9> counts{};
  for (const auto l : scene.labels) ++counts[static_cast<std::size_t>(l)];
  nlohmann::json j = {
      {"file", a.out},
      {"points", scene.cloud.size()},
      {"seed", a.scene.seed},
      {"rho_b", a.scene.rho_b},
      {"wall",
       {{"n", {scene.wall.n.x(), scene.wall.n.y(), scene.wall.n.z()}}, {"d", scene.wall.d}}}};
  for (std::size_t i = 0; i < counts.size(); ++i) {
    if (counts[i] > 0) j["labels"][dsp::label_name(static_cast<dsp::PointLabel>(i))] = counts[i];
  }
  if (a.json) {
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << "wrote " << a.out << ": " << scene.cloud.size() << " points";
    for (const auto& [k, v] : j["labels"].items()) std::cout << ", " << v << " " << k;
    std::cout << "; true wall n = (0, 0, -1), d = " << scene.wall.d << "\n";
  }
  return kExitOk;
}

struct SweepArgs {
  std::string name;
  std::string out = "eval_out";
  std::string seeds;
  std::string methods;
  std::map<std::string, std::string> grids;  // flag -> text, filled by the options below
  double threshold_m = -1.0;
  dsp::SuccessCriterion success;
  dsp::ThesisSceneParams scene;
  double rho_b = -1.0;
  bool no_plots = false;
  bool json = false;
};

// All the checks that can fail on the command line happen before any trial runs or any file is
// written (issue 4: no partial results that look complete).
eval::SweepOptions sweep_options(const SweepArgs& a) {
  eval::SweepOptions o;
  if (!a.seeds.empty()) o.seeds = eval::parse_seeds(a.seeds);
  o.success = a.success;
  o.scene = a.scene;
  if (a.rho_b >= 0) o.scene.rho_b = a.rho_b;
  if (a.threshold_m > 0) o.threshold_m = a.threshold_m;
  if (!a.methods.empty()) {
    std::string_view rest(a.methods);
    for (;;) {
      const std::size_t comma = rest.find(',');
      o.methods.push_back(eval::parse_method(rest.substr(0, comma)));
      if (comma == std::string_view::npos) break;
      rest.remove_prefix(comma + 1);
    }
  }
  for (const auto& [flag, text] : a.grids) {
    if (text.empty()) continue;
    o.grids[flag] = eval::parse_range(text, flag);
  }
  return o;
}

void print_sweep(const nlohmann::json& j) {
  std::cout << j["sweep"].get<std::string>() << ": " << j["trials"] << " trials, "
            << j["seconds"].get<double>() << " s; success = " << j["success"].get<std::string>()
            << "\n  " << j["csv"].get<std::string>();
  if (!j["figure"].is_null()) std::cout << ", " << j["figure"].get<std::string>();
  std::cout << "\n";
}

int run_sweep_command(const SweepArgs& a) {
  const eval::SweepOptions o = sweep_options(a);
  eval::check_sweep(a.name, o);
  if (!a.no_plots && !eval::gnuplot_available()) {
    throw std::runtime_error(
        "gnuplot is not installed (tools/setup installs gnuplot-nox); "
        "--no-plots writes the CSV only");
  }
  eval::OutputDir out(a.out, !a.no_plots);
  const nlohmann::json j = eval::run_sweep(a.name, o, out, &std::cerr);
  out.write(a.name + ".json", j.dump(2) + "\n");
  if (a.json) {
    std::cout << j.dump(2) << "\n";
  } else {
    print_sweep(j);
  }
  return kExitOk;
}

struct AllArgs {
  std::string recording;
  std::string out = "eval_out";
  bool no_plots = false;
  bool quick = false;
  bool json = false;
};

int run_all_command(const AllArgs& a) {
  if (!a.no_plots && !eval::gnuplot_available()) {
    throw std::runtime_error(
        "gnuplot is not installed (tools/setup installs gnuplot-nox); "
        "--no-plots writes the CSVs only");
  }
  const auto t0 = std::chrono::steady_clock::now();
  // The recording is read (and checked) before anything is written.
  recording::ReadOptions read_options;
  read_options.check_image_files = false;
  const CameraCalibration cam0 = read_recording_reporting(a.recording, read_options).cams[0].calib;
  eval::OutputDir out(a.out, !a.no_plots);
  nlohmann::json all = {{"sweeps", nlohmann::json::array()}};
  // Fig. 4.1: one scene of each kind, as files to look at.
  dsp::ThesisSceneParams scene;
  scene.rho_b = 0.2;
  eval::write_labelled_scene(dsp::make_thesis_scene(scene), out.path() / "synth_scene.ply");
  for (const std::string& name : eval::sweep_names()) {
    if (stop_requested().load()) return kExitInterrupted;
    eval::SweepOptions o;
    if (a.quick) o.seeds = {1, 2, 3};
    const nlohmann::json j = eval::run_sweep(name, o, out, &std::cerr);
    out.write(name + ".json", j.dump(2) + "\n");
    if (!a.json) print_sweep(j);
    all["sweeps"].push_back(j);
  }
  if (stop_requested().load()) return kExitInterrupted;
  eval::RealStudyOptions real;
  real.recording = a.recording;
  real.appliance_map = appliance_map_for_study;
  all["real"] = eval::run_real_study(real, out);
  std::cerr << "real: done\n";
  if (eval::aruco_available()) {
    eval::MarkerStudyOptions marker;
    if (a.quick) marker.seeds = 1;
    all["marker"] = eval::run_marker_study(marker, cam0, out);
    std::cerr << "marker: done\n";
  } else {
    all["marker"] = "not in this build (ArUco is host-only)";
  }
  all["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.write("summary.json", all.dump(2) + "\n");
  if (a.json) {
    std::cout << all.dump(2) << "\n";
  } else {
    std::cout << "all results in " << a.out << "/ (" << all["seconds"].get<double>() << " s)\n";
  }
  return kExitOk;
}

}  // namespace

void add_eval_command(CLI::App& app, std::function<int()>& run) {
  CLI::App* eval = app.add_subcommand(
      "eval", "Evaluation suite: the thesis's experiments, runtime, real data, marker truth");
  eval->require_subcommand(1);

  auto synth = std::make_shared<SynthArgs>();
  CLI::App* s = eval->add_subcommand(
      "synth", "Write the thesis's artificial scene (4.1) with per-point labels (PLY or CSV)");
  add_scene_flags(*s, synth->scene, true);
  s->add_option("--rho-b", synth->scene.rho_b, "Backlier probability of the data")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.95));
  s->add_option("--seed", synth->scene.seed, "Random seed")->capture_default_str();
  s->add_option("--out", synth->out, "Output file, .ply or .csv")->required();
  s->add_flag("--json", synth->json, "Print counts and the true wall as JSON");
  s->callback([synth, &run] { run = [synth] { return run_synth(*synth); }; });

  auto sweep = std::make_shared<SweepArgs>();
  std::string names;
  for (const auto& n : eval::sweep_names()) names += (names.empty() ? "" : ", ") + n;
  CLI::App* w = eval->add_subcommand(
      "sweep", "Run one experiment over a grid and many seeds; CSV + PNG + JSON into --out");
  w->add_option("name", sweep->name, "Sweep: " + names)->required();
  w->add_option("--out", sweep->out, "Output folder")->capture_default_str();
  w->add_option("--seeds", sweep->seeds, "Seeds, A-B or A,B,C (default: the sweep's)");
  w->add_option("--methods", sweep->methods,
                "methods/windows/clutter: comma list of ransac, msac, bsf, binomial, pcl, open3d");
  for (const char* g : {"beta", "rho", "rho-b", "threshold-m", "gravity-error-deg", "points",
                        "inlier-ratio", "window-points", "clutter-points"}) {
    w->add_option(std::string("--") + g, sweep->grids[g],
                  "Grid LO:HI:STEP or A,B,C (only for the sweeps that take it)");
  }
  w->add_option("--threshold", sweep->threshold_m,
                "Inlier threshold [m] where the sweep does not vary it (default: the sweep's)");
  w->add_option("--scene-rho-b", sweep->rho_b,
                "rho_b of the scene where the sweep does not vary it (default 0.3)")
      ->check(CLI::Range(0.0, 0.95));
  add_scene_flags(*w, sweep->scene, false);
  w->add_option("--success-angle-deg", sweep->success.max_angle_deg,
                "Success: normal within this angle of the true wall's")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 90.0));
  w->add_option("--success-offset-m", sweep->success.max_offset_m,
                "Success: and offset within this distance")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  w->add_flag("--no-plots", sweep->no_plots, "Write CSV and gnuplot script, do not draw");
  w->add_flag("--json", sweep->json, "Print the summary as JSON");
  w->callback([sweep, &run] { run = [sweep] { return run_sweep_command(*sweep); }; });

  auto all = std::make_shared<AllArgs>();
  CLI::App* l = eval->add_subcommand("all", "Regenerate every result of docs/results.md");
  l->add_option("--recording", all->recording,
                "EuRoC recording for the real-data and marker studies, e.g. "
                "tests/data/euroc_v1_01_still")
      ->required()
      ->check(CLI::ExistingPath);
  l->add_option("--out", all->out, "Output folder")->capture_default_str();
  l->add_flag("--quick", all->quick, "3 seeds per sweep instead of the defaults (smoke test)");
  l->add_flag("--no-plots", all->no_plots, "Write CSVs and gnuplot scripts, do not draw");
  l->add_flag("--json", all->json, "Print the summary as JSON");
  l->callback([all, &run] { run = [all] { return run_all_command(*all); }; });
  add_eval_real_command(*eval, run);
  add_eval_marker_command(*eval, run);
  add_eval_synth_rig_command(*eval, run);
}

}  // namespace wallar::cli
