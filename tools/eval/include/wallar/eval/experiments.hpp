// SPDX-License-Identifier: Apache-2.0
/// @file experiments.hpp
/// @brief The thesis's experiments (ch. 4) and the ones it left open, as sweeps over the
/// artificial scenes of dsp/walls/synthetic.hpp. Every sweep runs one trial per grid cell and
/// seed, scores it with eq. 3.6 (accuracy) and eq. 3.7 (robustness), writes a CSV and a figure
/// into an OutputDir, and returns a JSON summary.
///
/// Sweeps (name: what, grid flags):
///  - bsf:          fig. 4.2, BSF-RANSAC success over (beta, data rho_b)      --beta --rho-b
///  - binomial:     fig. 4.3, B-RANSAC success over (rho set, data rho_b)     --rho --rho-b
///  - threshold:    fig. 4.4, RMSE and inliers vs the inlier threshold         --threshold-m
///  - methods:      robustness vs rho_b: RANSAC, MSAC, BSF, B-RANSAC, PCL, Open3D  --rho-b
///  - gravity:      2-D (gravity) vs 3-D accuracy with a perturbed gravity     --gravity-error-deg
///  - runtime:      time per detection vs points and inlier ratio, 3-D/2-D, uniform/guided
///                                                                  --points --inlier-ratio
///  - rounds:       rounds taken vs eq. 2.7's, over the inlier ratio           --inlier-ratio
///  - windows:      robustness with a window (a patch of backliers)           --window-points
///  - clutter:      robustness with boxes in front of the wall                 --clutter-points
///  - rho-estimate: B-RANSAC's rho_b estimated from the data vs the true one   --rho-b
///
/// Threading: functions run on the calling thread; call from one thread at a time (the
/// Open3D peer is process-wide).
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/dsp/eval/metrics.hpp"
#include "wallar/dsp/walls/synthetic.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"
#include "wallar/eval/output.hpp"

namespace wallar::eval {

/// Values for one axis of a sweep: "LO:HI:STEP" (inclusive, tolerant of rounding) or a list
/// "A,B,C". Throws InputError("--FLAG: ...") for an empty range, a step <= 0, a non-number or
/// more than 10,000 values.
std::vector<double> parse_range(std::string_view text, std::string_view flag);

/// Seeds: "A-B" (inclusive) or "A,B,C" of unsigned integers. Throws InputError("--seeds: ...")
/// for anything else, an empty or reversed range, or more than 100,000 seeds.
std::vector<std::uint64_t> parse_seeds(std::string_view text);

/// Methods compared: the detector's scores, and the peers.
enum class Method : std::uint8_t { kRansac, kMsac, kBsf, kBinomial, kPcl, kOpen3d };
/// "ransac", "msac", "bsf", "binomial", "pcl", "open3d"; InputError("--methods: ...") otherwise.
Method parse_method(std::string_view name);
const char* method_name(Method m);

/// One detection on a labelled scene.
struct TrialSetup {
  Method method = Method::kBsf;
  double threshold_m = 0.1;
  double beta = 0.5;  //!< kBsf
  double rho = -1.0;  //!< kBinomial: set value; < 0 estimates it from the data
  /// 2-D mode: gravity (down, scene frame), possibly perturbed; nothing: 3-D.
  std::optional<Eigen::Vector3d> gravity;
  dsp::Sampling sampling = dsp::Sampling::kGuided;
  double confidence = 0.99;
  std::uint32_t max_rounds = 200'000;
  std::uint64_t seed = 1;
};
struct TrialResult {
  bool found = false;
  bool success = false;
  Plane plane;
  dsp::PlaneError error;
  double rmse_m = 0.0;  //!< eq. 3.6 over the estimate's inliers
  std::uint32_t inliers = 0;
  std::uint32_t rounds = 0;
  std::uint32_t rounds_needed = 0;
  double rho_b = 0.0;  //!< B-RANSAC: the rho_b it used (estimated or set)
  double time_ms = 0.0;
};
TrialResult run_trial(const dsp::LabelledCloud& scene, const TrialSetup& setup,
                      const dsp::SuccessCriterion& success);

/// Everything a sweep can be told. Grids left empty take the sweep's defaults (see the .cpp).
struct SweepOptions {
  std::vector<std::uint64_t> seeds;  //!< empty: the sweep's default
  dsp::SuccessCriterion success;
  dsp::ThesisSceneParams scene;       //!< the §4.1 scene (its seed and rho_b are set per trial)
  std::optional<double> threshold_m;  //!< the scene's inlier threshold (default: thesis 0.1 m)
  std::vector<Method> methods;        //!< "methods" sweep; empty: all this build has
  std::map<std::string, std::vector<double>> grids;  //!< "beta", "rho-b", ... (flag names)
};

/// The sweeps' names, in the order `wallar eval all` runs them.
const std::vector<std::string>& sweep_names();
/// The grid flags a sweep takes (e.g. {"beta", "rho-b"} for "bsf").
std::vector<std::string> sweep_grids(std::string_view sweep);

/// InputError for an unknown sweep name or a grid flag the sweep does not take.
void check_sweep(std::string_view name, const SweepOptions& options);

/// Runs sweep `name` (check_sweep() first), writing
/// NAME.csv, NAME.gp and NAME.png into `out`. `progress` (may be null) gets a line per step.
nlohmann::json run_sweep(std::string_view name, const SweepOptions& options, OutputDir& out,
                         std::ostream* progress = nullptr);

/// `wallar eval synth`: the scene as PLY (x y z, colour by label, uchar label) or CSV
/// (x,y,z,label) by the path's extension; InputError for another extension.
void write_labelled_scene(const dsp::LabelledCloud& scene, const std::filesystem::path& path);

}  // namespace wallar::eval
