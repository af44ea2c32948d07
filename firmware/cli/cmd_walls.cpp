// SPDX-License-Identifier: Apache-2.0
/// @file cmd_walls.cpp
/// @brief `wallar walls INPUT`: walls, floor and ceiling of a point cloud file.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/cloud/cloud_io.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/firmware/report.hpp"

namespace wallar::cli {
namespace {

struct WallsArgs {
  std::string input;
  std::string method = score_method_name(dsp::RoomConfig{}.detector.method);
  std::string sampling = "guided";
  double beta = 0.5;
  double rho = -1.0;
  double threshold_m = 0.05;
  std::string gravity;
  std::vector<std::string> viewpoints;
  std::string view_dir = "0,0,1";
  int max_walls = 6;
  double confidence = 0.99;
  std::uint32_t max_rounds = dsp::RoomConfig{}.detector.max_rounds;
  std::uint64_t seed = 1;
  bool manhattan = false;
  double surface_sigma = dsp::RoomConfig{}.min_excess_sigma;
  std::string json;
  std::string ply;
};

Eigen::Vector3d parse_vec3(const std::string& text, const char* option) {
  Eigen::Vector3d v;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &v.x(), &v.y(), &v.z(), &tail) != 3 ||
      !v.allFinite()) {
    throw CLI::ValidationError(option, "expects x,y,z (three numbers), got '" + text + "'");
  }
  return v;
}

/// Where the time went: set-up, each search in turn (what it ended with), extents and ids.
std::string stage_times(const dsp::RoomResult& r) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(2);
  out << "  time: set-up " << 1e3 * ns_to_s(r.setup_ns) << " ms\n";
  for (std::size_t i = 0; i < r.searches.size(); ++i) {
    const dsp::RoomSearch& s = r.searches[i];
    out << "  time: search " << i + 1 << " " << 1e3 * ns_to_s(s.time_ns) << " ms (" << s.rounds
        << " rounds)";
    if (s.horizontal_rounds > 0) {
      out << " + floor/ceiling " << 1e3 * ns_to_s(s.horizontal_time_ns) << " ms ("
          << s.horizontal_rounds << " rounds)";
    }
    out << ": " << dsp::to_string(s.outcome);
    if (s.found_surface()) {
      out << " (" << to_string(s.kind) << ", " << s.inliers << " inliers)";
    } else if (s.outcome == dsp::RoomSearch::Outcome::kTooSmall) {
      out << " (best " << s.inliers << " inliers)";
    }
    out << "\n";
  }
  out << "  time: extents, merges and ids " << 1e3 * ns_to_s(r.finish_ns) << " ms\n";
  return out.str();
}

int run_walls_command(const WallsArgs& a) {
  cloud::CloudReadStats read_stats;
  const PointCloud cloud = cloud::read_cloud(a.input, &read_stats);
  if (read_stats.points_read < 3) {
    throw_input_error(a.input, 0,
                      "needs at least 3 valid points, has " +
                          std::to_string(read_stats.points_read) + " (" +
                          std::to_string(read_stats.non_finite_skipped) + " non-finite skipped)");
  }
  dsp::RoomConfig cfg;
  cfg.detector.method = score_method_named(a.method);
  cfg.detector.sampling =
      a.sampling == "uniform" ? dsp::Sampling::kUniform : dsp::Sampling::kGuided;
  cfg.detector.beta = a.beta;
  cfg.detector.rho_b = a.rho;
  cfg.detector.threshold_m = a.threshold_m;
  cfg.detector.confidence = a.confidence;
  cfg.detector.max_rounds = a.max_rounds;
  cfg.detector.min_rounds = std::min(cfg.detector.min_rounds, a.max_rounds);
  cfg.detector.seed = a.seed;
  cfg.detector.view_dir = parse_vec3(a.view_dir, "--view-dir");
  if (!(cfg.detector.view_dir.norm() > 0.0)) {
    throw CLI::ValidationError("--view-dir", "must not be the zero vector");
  }
  if (!a.gravity.empty()) {
    const Eigen::Vector3d g = parse_vec3(a.gravity, "--gravity");
    if (!(g.norm() > 1e-9)) throw CLI::ValidationError("--gravity", "must not be the zero vector");
    cfg.gravity = g;
  }
  if (!a.viewpoints.empty()) {
    cfg.viewpoints.clear();
    for (const auto& v : a.viewpoints) cfg.viewpoints.push_back(parse_vec3(v, "--viewpoint"));
    if (cfg.viewpoints.size() > 64) throw CLI::ValidationError("--viewpoint", "at most 64");
  }
  cfg.max_surfaces = a.max_walls;
  cfg.min_excess_sigma = a.surface_sigma;
  cfg.manhattan = a.manhattan;

  dsp::RoomEstimator estimator(cloud.size());
  const TimeNs t0 = monotonic_now_ns();
  const dsp::RoomResult result = estimator.estimate(cloud, cfg);
  const double time_ms = static_cast<double>(monotonic_now_ns() - t0) * 1e-6;

  std::ostringstream text;
  text << "wallar walls: " << result.points << " points";
  if (read_stats.non_finite_skipped) {
    text << " (" << read_stats.non_finite_skipped << " non-finite skipped)";
  }
  text << ", " << (cfg.gravity ? "2-D (gravity-aligned)" : "3-D") << " " << a.method << ", "
       << result.rounds << " rounds, " << time_ms << " ms\n"
       << firmware::to_text(result) << stage_times(result);
  nlohmann::json out = firmware::to_json(result);
  out["non_finite_skipped"] = read_stats.non_finite_skipped;
  out["time_ms"] = time_ms;
  if (a.json == "-") {
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << text.str();
    if (!a.json.empty()) {
      std::ofstream f(a.json);
      f << out.dump(2) << "\n";
      if (!f) throw std::runtime_error(a.json + ": cannot write");
    }
  }
  if (!a.ply.empty()) {
    const auto rgb = firmware::surface_colours(cloud, result, a.threshold_m);
    cloud::write_ply_rgb(a.ply, cloud, rgb);
  }
  return kExitOk;
}

}  // namespace

void add_walls_command(CLI::App& app, std::function<int()>& run) {
  auto a = std::make_shared<WallsArgs>();
  CLI::App* cmd = app.add_subcommand("walls", "Find walls, floor and ceiling in a point cloud");
  cmd->add_option("input", a->input, "Point cloud: .ply, .pcd or .csv (x,y,z)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--method", a->method,
                  "Score: ransac, msac, bsf (BSF-RANSAC), binomial (B-RANSAC) or contrast (BSF "
                  "on the band's contrast: its inner half less half its outer half)")
      ->check(CLI::IsMember(kScoreMethodNames))
      ->capture_default_str();
  cmd->add_option("--sampling", a->sampling, "uniform or guided (neighbourhood) sampling")
      ->check(CLI::IsMember({"uniform", "guided"}))
      ->capture_default_str();
  cmd->add_option("--beta", a->beta, "BSF backlier weight")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--rho", a->rho,
                  "B-RANSAC backlier probability (default: estimated from the data)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--threshold", a->threshold_m, "Inlier threshold [m]")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--gravity", a->gravity,
                  "Gravity gx,gy,gz in the cloud's frame: 2-D mode, floor and ceiling");
  cmd->add_option("--viewpoint", a->viewpoints, "Camera centre x,y,z (repeatable; default origin)");
  cmd->add_option("--view-dir", a->view_dir, "Viewing direction for the 3-D facing check")
      ->capture_default_str();
  cmd->add_option("--surface-sigma", a->surface_sigma,
                  "Report only surfaces whose band holds this many standard deviations more "
                  "points than the bands beside it (e.g. 4; 0: off)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--max-walls", a->max_walls, "Most surfaces to report")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  cmd->add_option("--confidence", a->confidence, "Success probability for the rounds (eq. 2.7)")
      ->check(CLI::Range(0.5, 0.999999))
      ->capture_default_str();
  cmd->add_option("--max-rounds", a->max_rounds, "Cap on RANSAC rounds per surface")
      ->check(CLI::Range(1u, 100'000'000u))
      ->capture_default_str();
  cmd->add_option("--seed", a->seed, "Random seed")->capture_default_str();
  cmd->add_flag("--manhattan", a->manhattan,
                "Walls parallel or perpendicular to the first (with --gravity)");
  cmd->add_option("--json", a->json, "Write the result as JSON to FILE, or - for stdout");
  cmd->add_option("--ply", a->ply, "Write the points coloured by surface as PLY");
  cmd->callback([a, &run] { run = [a] { return run_walls_command(*a); }; });
}

}  // namespace wallar::cli
