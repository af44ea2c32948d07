// SPDX-License-Identifier: Apache-2.0
/// @file experiments.cpp
/// @brief The sweeps of `wallar eval sweep`: trials, grids, CSVs, figures, summaries.
#include "wallar/eval/experiments.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <ostream>
#include <random>
#include <set>

#include "wallar/core/error.hpp"
#include "wallar/eval/peers.hpp"

namespace wallar::eval {
namespace {

[[noreturn]] void flag_error(std::string_view flag, const std::string& msg) {
  throw InputError("--" + std::string(flag) + ": " + msg);
}

std::optional<double> to_double(std::string_view s) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  while (!s.empty() && s.back() == ' ') s.remove_suffix(1);
  double v = 0.0;
  const auto res = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || res.ec != std::errc() || res.ptr != s.data() + s.size() || !std::isfinite(v)) {
    return std::nullopt;
  }
  return v;
}

std::optional<std::uint64_t> to_u64(std::string_view s) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  while (!s.empty() && s.back() == ' ') s.remove_suffix(1);
  std::uint64_t v = 0;
  const auto res = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || res.ec != std::errc() || res.ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> out;
  for (;;) {
    const std::size_t at = s.find(sep);
    out.push_back(s.substr(0, at));
    if (at == std::string_view::npos) return out;
    s.remove_prefix(at + 1);
  }
}

constexpr std::size_t kMaxGridValues = 10'000;
constexpr std::size_t kMaxSeeds = 100'000;

// ---- trials -------------------------------------------------------------------------------

dsp::ScoreMethod score_of(Method m) {
  switch (m) {
    case Method::kRansac:
      return dsp::ScoreMethod::kRansac;
    case Method::kMsac:
      return dsp::ScoreMethod::kMsac;
    case Method::kBinomial:
      return dsp::ScoreMethod::kBinomial;
    default:
      return dsp::ScoreMethod::kBsf;
  }
}

double mean(const std::vector<double>& v) {
  if (v.empty()) return 0.0;
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

double median_or_zero(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

// Gravity (+y, down, in the scenes' camera-like frame) tilted by angle_deg about a horizontal
// axis whose direction is drawn from the seed (raw generator bits: the same on every platform).
Eigen::Vector3d perturbed_gravity(double angle_deg, std::uint64_t seed) {
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + 7);
  const double phi = static_cast<double>(rng() >> 11) * 0x1.0p-53 * 2.0 * M_PI;
  const Eigen::Vector3d axis(std::cos(phi), 0.0, std::sin(phi));
  return Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis) * Eigen::Vector3d::UnitY();
}

// ---- grids and output helpers --------------------------------------------------------------

struct SweepDef {
  const char* name;
  std::vector<std::pair<const char*, const char*>> grids;  // flag, default range
  const char* seeds;                                       // default seeds
};

const std::vector<SweepDef>& sweep_defs() {
  static const std::vector<SweepDef> defs = {
      {"bsf", {{"beta", "0:2:0.1"}, {"rho-b", "0:0.9:0.05"}}, "1-10"},
      {"binomial", {{"rho", "0.05:0.95:0.05"}, {"rho-b", "0:0.9:0.05"}}, "1-10"},
      {"threshold",
       {{"threshold-m", "0.0025,0.005,0.01,0.02,0.03,0.05,0.075,0.1,0.15,0.2,0.3,0.4"}},
       "1-20"},
      {"methods", {{"rho-b", "0:0.8:0.1"}}, "1-20"},
      {"gravity", {{"gravity-error-deg", "0:5:0.5"}}, "1-20"},
      {"runtime", {{"points", "1000,3000,10000,30000"}, {"inlier-ratio", "0.05,0.1,0.3"}}, "1-3"},
      {"rounds", {{"inlier-ratio", "0.02,0.03,0.05,0.075,0.1,0.15,0.2,0.3,0.5"}}, "1-10"},
      {"windows", {{"window-points", "0:400:50"}}, "1-20"},
      {"clutter", {{"clutter-points", "0:1000:100"}}, "1-20"},
      {"rho-estimate", {{"rho-b", "0:0.9:0.05"}}, "1-20"},
  };
  return defs;
}

const SweepDef& find_sweep(std::string_view name) {
  for (const auto& d : sweep_defs()) {
    if (name == d.name) return d;
  }
  std::string known;
  for (const auto& d : sweep_defs()) known += std::string(known.empty() ? "" : ", ") + d.name;
  throw InputError("unknown sweep '" + printable(name) + "' (known: " + known + ")");
}

class Context {
 public:
  Context(const SweepDef& def, const SweepOptions& o, OutputDir& out, std::ostream* progress)
      : def_(def), o_(o), out_(out), progress_(progress) {
    check_sweep(def.name, o);
    seeds_ = o.seeds.empty() ? parse_seeds(def.seeds) : o.seeds;
    start_ = std::chrono::steady_clock::now();
  }

  std::vector<double> grid(const char* flag) const {
    const auto it = o_.grids.find(flag);
    if (it != o_.grids.end()) return it->second;
    for (const auto& g : def_.grids) {
      if (std::string_view(flag) == g.first) return parse_range(g.second, flag);
    }
    return {};
  }
  const std::vector<std::uint64_t>& seeds() const { return seeds_; }
  std::string name() const { return def_.name; }
  const SweepOptions& options() const { return o_; }
  const dsp::SuccessCriterion& success() const { return o_.success; }
  double threshold(double fallback) const { return o_.threshold_m.value_or(fallback); }
  OutputDir& out() { return out_; }

  TrialResult trial(const dsp::LabelledCloud& scene, const TrialSetup& s) {
    ++trials_;
    return run_trial(scene, s, o_.success);
  }
  void note(const std::string& line) {
    if (progress_ != nullptr) *progress_ << def_.name << ": " << line << "\n" << std::flush;
  }

  // Writes NAME.csv and the figure; the summary gets the common fields.
  nlohmann::json finish(const CsvTable& table, const std::string& script, nlohmann::json findings,
                        int width_px = 900, int height_px = 650) {
    const std::string name = def_.name;
    out_.write(name + ".csv", table.text());
    const auto png = out_.plot(name, script, width_px, height_px);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    nlohmann::json j = {{"sweep", name},
                        {"trials", trials_},
                        {"seeds", seeds_.size()},
                        {"seconds", seconds},
                        {"success", o_.success.describe()},
                        {"csv", name + ".csv"},
                        {"figure", png ? nlohmann::json(name + ".png") : nlohmann::json()},
                        {"findings", std::move(findings)}};
    char buf[96];
    std::snprintf(buf, sizeof buf, "%zu trials in %.1f s", trials_, seconds);
    note(buf);
    return j;
  }

 private:
  const SweepDef& def_;
  const SweepOptions& o_;
  OutputDir& out_;
  std::ostream* progress_;
  std::vector<std::uint64_t> seeds_;
  std::size_t trials_ = 0;
  std::chrono::steady_clock::time_point start_;
};

double half_step(const std::vector<double>& v) {
  double step = 0.0;
  for (std::size_t i = 1; i < v.size(); ++i) {
    const double d = std::abs(v[i] - v[i - 1]);
    if (d > 0 && (step == 0.0 || d < step)) step = d;
  }
  return step > 0 ? step / 2 : 0.5;
}

// "%g" (for plot scripts and progress lines).
std::string num(double a) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", a);
  return buf;
}

// A success map in the thesis's colours: white success, black failure, grey in between.
std::string heat_map_script(const std::string& csv, const std::string& title,
                            const std::string& xlabel, const std::string& ylabel,
                            const std::vector<double>& xs, const std::vector<double>& ys,
                            const std::string& success_text) {
  const double hx = half_step(xs), hy = half_step(ys);
  const auto [xmin, xmax] = std::minmax_element(xs.begin(), xs.end());
  const auto [ymin, ymax] = std::minmax_element(ys.begin(), ys.end());
  std::string s;
  s += "set title \"" + title + "\\n(" + success_text + ")\"\n";
  s += "set xlabel \"" + xlabel + "\"\nset ylabel \"" + ylabel + "\"\n";
  s += "set palette gray\nset cbrange [0:1]\nset cblabel \"robustness (eq. 3.7)\"\n";
  s += "set xrange [" + num(*xmin - hx) + ":" + num(*xmax + hx) + "]\n";
  s += "set yrange [" + num(*ymin - hy) + ":" + num(*ymax + hy) + "]\n";
  s += "set tics out\nunset key\n";
  s += "plot \"" + csv + "\" skip 1 using 1:2:(" + num(hx) + "):(" + num(hy) +
       "):5 with boxxyerror fs solid 1.0 noborder lc palette\n";
  return s;
}

// ---- the sweeps ------------------------------------------------------------------------------

dsp::LabelledCloud thesis_scene(const SweepOptions& o, double rho_b, std::uint64_t seed) {
  dsp::ThesisSceneParams p = o.scene;
  p.rho_b = rho_b;
  p.seed = seed;
  return dsp::make_thesis_scene(p);
}

// Fig. 4.2 / 4.3: a success map over (algorithm parameter, data rho_b).
nlohmann::json sweep_success_map(Context& c, bool binomial) {
  const char* param = binomial ? "rho" : "beta";
  const auto xs = c.grid(param);
  const auto ys = c.grid("rho-b");
  CsvTable t({param, "rho_b", "successes", "trials", "robustness", "mean_rmse_m"});
  TrialSetup s;
  s.method = binomial ? Method::kBinomial : Method::kBsf;
  s.threshold_m = c.threshold(0.1);
  nlohmann::json by_rho = nlohmann::json::array();
  for (double rho_b : ys) {
    std::vector<dsp::LabelledCloud> scenes;
    for (std::uint64_t seed : c.seeds()) scenes.push_back(thesis_scene(c.options(), rho_b, seed));
    std::vector<double> good;  // parameter values that succeeded in >= 90 % of the seeds
    for (double x : xs) {
      dsp::Robustness r;
      std::vector<double> rmse;
      for (std::size_t k = 0; k < scenes.size(); ++k) {
        s.seed = c.seeds()[k];
        if (binomial)
          s.rho = x;
        else
          s.beta = x;
        const TrialResult tr = c.trial(scenes[k], s);
        r.add(tr.success);
        if (tr.success) rmse.push_back(tr.rmse_m);
      }
      t.add(x).add(rho_b).add(r.successes).add(r.trials).add(r.value()).add(mean(rmse));
      t.end_row();
      if (r.value() >= 0.9) good.push_back(x);
    }
    nlohmann::json band = {{"rho_b", rho_b}};
    if (!good.empty()) {
      band[std::string(param) + "_min"] = good.front();
      band[std::string(param) + "_max"] = good.back();
    }
    by_rho.push_back(band);
    c.note("rho_b " + num(rho_b) + ": " + std::to_string(good.size()) + "/" +
           std::to_string(xs.size()) + " settings succeed in >= 90 % of seeds");
  }
  const std::string title = binomial ? "B-RANSAC (eq. 3.4): rho set vs the data's rho_b (fig. 4.3)"
                                     : "BSF-RANSAC (eq. 3.1): beta vs the data's rho_b (fig. 4.2)";
  const std::string xlabel = binomial ? "rho_b set in the algorithm" : "beta (backlier weight)";
  return c.finish(t,
                  heat_map_script(binomial ? "binomial.csv" : "bsf.csv", title, xlabel,
                                  "rho_b of the data", xs, ys, c.success().describe()),
                  {{"success_band_90pct", by_rho}});
}

// Fig. 4.4: accuracy (eq. 3.6) and inlier count vs the threshold, on a scene with one dominant
// plane (the thesis's setting for this test: its real cloud had only the marker's wall).
nlohmann::json sweep_threshold(Context& c) {
  const auto ts = c.grid("threshold-m");
  CsvTable t({"threshold_m", "method", "mean_rmse_m", "mean_inliers", "robustness"});
  SweepOptions o = c.options();
  o.scene.plane_points = 0;
  nlohmann::json best;
  for (Method m : {Method::kRansac, Method::kBsf}) {
    double best_rmse = 1e9, best_t = 0.0;
    for (double th : ts) {
      TrialSetup s;
      s.method = m;
      s.threshold_m = th;
      dsp::Robustness r;
      std::vector<double> rmse, inl;
      for (std::uint64_t seed : c.seeds()) {
        s.seed = seed;
        const TrialResult tr = c.trial(thesis_scene(o, o.scene.rho_b, seed), s);
        r.add(tr.success);
        if (tr.found) {
          rmse.push_back(tr.rmse_m);
          inl.push_back(tr.inliers);
        }
      }
      t.add(th).add(method_name(m)).add(mean(rmse)).add(mean(inl)).add(r.value());
      t.end_row();
      if (r.value() >= 0.9 && mean(rmse) < best_rmse) best_rmse = mean(rmse), best_t = th;
    }
    best[method_name(m)] = {{"best_threshold_m", best_t}, {"mean_rmse_m", best_rmse}};
  }
  const std::string script =
      "set multiplot layout 2,1 title \"Threshold vs accuracy (fig. 4.4); wall noise " +
      num(o.scene.noise_m) +
      " m (uniform, full width)\"\n"
      "set logscale x\nset xlabel \"inlier threshold [m]\"\nset key top left\nset grid\n"
      "set ylabel \"RMSE, eq. 3.6 [mm]\"\n"
      "plot \"threshold.csv\" skip 1 using 1:(strcol(2) eq \"ransac\" ? $3*1000 : NaN) with "
      "linespoints title \"RANSAC\", \"\" skip 1 using 1:(strcol(2) eq \"bsf\" ? $3*1000 : NaN) "
      "with linespoints title \"BSF-RANSAC\"\n"
      "set ylabel \"inliers\"\n"
      "plot \"threshold.csv\" skip 1 using 1:(strcol(2) eq \"ransac\" ? $4 : NaN) with "
      "linespoints title \"RANSAC\", \"\" skip 1 using 1:(strcol(2) eq \"bsf\" ? $4 : NaN) with "
      "linespoints title \"BSF-RANSAC\"\n"
      "unset multiplot\n";
  return c.finish(t, script, best, 900, 900);
}

std::vector<Method> methods_to_run(const SweepOptions& o) {
  if (!o.methods.empty()) return o.methods;
  std::vector<Method> m = {Method::kRansac, Method::kMsac, Method::kBsf, Method::kBinomial};
  if (peers_available()) {
    m.push_back(Method::kPcl);
    m.push_back(Method::kOpen3d);
  }
  return m;
}

// Curves of robustness over one grid for several methods, on thesis scenes made by `make`.
nlohmann::json sweep_curves(Context& c, const char* flag, const std::vector<Method>& methods,
                            const std::function<dsp::LabelledCloud(double, std::uint64_t)>& make,
                            const std::string& title, const std::string& xlabel) {
  const auto xs = c.grid(flag);
  CsvTable t({flag, "method", "successes", "trials", "robustness", "mean_rmse_m"});
  nlohmann::json findings;
  for (double x : xs) {
    std::vector<dsp::LabelledCloud> scenes;
    for (std::uint64_t seed : c.seeds()) scenes.push_back(make(x, seed));
    std::string line = std::string(flag) + " " + num(x) + ":";
    for (Method m : methods) {
      TrialSetup s;
      s.method = m;
      s.threshold_m = c.threshold(0.1);
      dsp::Robustness r;
      std::vector<double> rmse;
      for (std::size_t k = 0; k < scenes.size(); ++k) {
        s.seed = c.seeds()[k];
        const TrialResult tr = c.trial(scenes[k], s);
        r.add(tr.success);
        if (tr.success) rmse.push_back(tr.rmse_m);
      }
      t.add(x).add(method_name(m)).add(r.successes).add(r.trials).add(r.value()).add(mean(rmse));
      t.end_row();
      findings[method_name(m)].push_back({{flag, x}, {"robustness", r.value()}});
      line += std::string(" ") + method_name(m) + " " + num(r.value());
    }
    c.note(line);
  }
  std::string script = "set title \"" + title + "\\n(" + c.success().describe() + ")\"\n";
  script += "set xlabel \"" + xlabel + "\"\nset ylabel \"robustness (eq. 3.7)\"\n";
  script += "set yrange [-0.05:1.05]\nset grid\nset key outside right\n";
  script += "plot ";
  for (std::size_t i = 0; i < methods.size(); ++i) {
    const std::string name = method_name(methods[i]);
    script += (i ? std::string(", \"\"") : "\"" + c.name() + ".csv\"") +
              " skip 1 using 1:(strcol(2) eq \"" + name +
              "\" ? $5 : NaN) with linespoints lw 2 title \"" + name + "\"";
  }
  script += "\n";
  return c.finish(t, script, findings);
}

nlohmann::json sweep_gravity(Context& c) {
  const auto angles = c.grid("gravity-error-deg");
  CsvTable t({"gravity_error_deg", "mode", "mean_rmse_m", "mean_normal_error_deg", "robustness"});
  nlohmann::json findings;
  std::vector<dsp::LabelledCloud> scenes;
  for (std::uint64_t seed : c.seeds()) {
    scenes.push_back(thesis_scene(c.options(), c.options().scene.rho_b, seed));
  }
  for (double a : angles) {
    for (const bool two_d : {false, true}) {
      TrialSetup s;
      s.threshold_m = c.threshold(0.1);
      dsp::Robustness r;
      std::vector<double> rmse, err;
      for (std::size_t k = 0; k < scenes.size(); ++k) {
        s.seed = c.seeds()[k];
        if (two_d) s.gravity = perturbed_gravity(a, s.seed);
        const TrialResult tr = c.trial(scenes[k], s);
        r.add(tr.success);
        if (tr.found) {
          rmse.push_back(tr.rmse_m);
          err.push_back(tr.error.angle_deg);
        }
      }
      const char* mode = two_d ? "2d" : "3d";
      t.add(a).add(mode).add(mean(rmse)).add(mean(err)).add(r.value());
      t.end_row();
      findings[mode].push_back(
          {{"gravity_error_deg", a}, {"mean_rmse_m", mean(rmse)}, {"robustness", r.value()}});
    }
  }
  const std::string script =
      "set multiplot layout 2,1 title \"2-D (gravity-aligned) vs 3-D BSF-RANSAC with a perturbed "
      "gravity (thesis 4.3)\"\n"
      "set xlabel \"gravity error [deg]\"\nset grid\nset key top left\n"
      "set ylabel \"RMSE, eq. 3.6 [mm]\"\n"
      "plot \"gravity.csv\" skip 1 using 1:(strcol(2) eq \"3d\" ? $3*1000 : NaN) with "
      "linespoints lw 2 title \"3-D (no gravity)\", \"\" skip 1 using 1:(strcol(2) eq \"2d\" ? "
      "$3*1000 : NaN) with linespoints lw 2 title \"2-D with gravity\"\n"
      "set ylabel \"normal error [deg]\"\n"
      "plot \"gravity.csv\" skip 1 using 1:(strcol(2) eq \"3d\" ? $4 : NaN) with linespoints lw 2 "
      "title \"3-D (no gravity)\", \"\" skip 1 using 1:(strcol(2) eq \"2d\" ? $4 : NaN) with "
      "linespoints lw 2 title \"2-D with gravity\"\n"
      "unset multiplot\n";
  return c.finish(t, script, findings, 900, 900);
}

struct Mode {
  const char* name;
  bool two_d;
  dsp::Sampling sampling;

  /// The trial this mode runs: its sampling, and gravity (the scene's +y) in the 2-D modes.
  [[nodiscard]] TrialSetup setup(double threshold_m) const {
    TrialSetup s;
    s.threshold_m = threshold_m;
    s.sampling = sampling;
    if (two_d) s.gravity = Eigen::Vector3d::UnitY();
    return s;
  }
};
constexpr Mode kModes[] = {{"3d-uniform", false, dsp::Sampling::kUniform},
                           {"3d-guided", false, dsp::Sampling::kGuided},
                           {"2d-uniform", true, dsp::Sampling::kUniform},
                           {"2d-guided", true, dsp::Sampling::kGuided}};

dsp::LabelledCloud sparse_scene(double points, double ratio, std::uint64_t seed) {
  dsp::SparseMapParams p;
  p.points = static_cast<std::size_t>(points);
  p.wall_fraction = ratio;
  p.seed = seed;
  return dsp::make_sparse_map(p);
}

nlohmann::json sweep_runtime(Context& c) {
  const auto points = c.grid("points");
  const auto ratios = c.grid("inlier-ratio");
  for (double p : points) {
    if (p < 10 || p > 5e6 || p != std::floor(p))
      flag_error("points", "each value must be an integer in 10..5000000");
  }
  CsvTable t({"mode", "points", "inlier_ratio", "median_time_ms", "median_rounds", "robustness"});
  nlohmann::json findings;
  for (double ratio : ratios) {
    for (double n : points) {
      std::vector<dsp::LabelledCloud> scenes;
      for (std::uint64_t seed : c.seeds()) scenes.push_back(sparse_scene(n, ratio, seed));
      for (const Mode& m : kModes) {
        TrialSetup s = m.setup(c.threshold(0.05));
        std::vector<double> ms, rounds;
        dsp::Robustness r;
        c.trial(scenes.front(), s);  // warm-up: caches, page faults, SIMD dispatch
        for (std::size_t k = 0; k < scenes.size(); ++k) {
          s.seed = c.seeds()[k];
          const TrialResult tr = c.trial(scenes[k], s);
          ms.push_back(tr.time_ms);
          rounds.push_back(tr.rounds);
          r.add(tr.success);
        }
        t.add(m.name).add(n).add(ratio).add(median_or_zero(ms)).add(median_or_zero(rounds)).add(r.value());
        t.end_row();
        findings[m.name].push_back({{"points", n},
                                    {"inlier_ratio", ratio},
                                    {"median_time_ms", median_or_zero(ms)},
                                    {"robustness", r.value()}});
      }
      c.note("ratio " + num(ratio) + ", " + num(n) + " points done");
    }
  }
  std::string script =
      "set multiplot layout 1," + std::to_string(ratios.size()) +
      " title \"Time per detection (one core; median over seeds)\"\n"
      "set logscale xy\nset xlabel \"points\"\nset ylabel \"time [ms]\"\nset grid\n"
      "set key top left font \",9\"\n";
  for (double ratio : ratios) {
    script += "set title \"wall fraction " + num(ratio) + "\"\nplot ";
    for (std::size_t i = 0; i < std::size(kModes); ++i) {
      script += std::string(i ? ", \"\"" : "\"runtime.csv\"") + " skip 1 using 2:(strcol(1) eq \"" +
                kModes[i].name + "\" && abs($3-" + num(ratio) +
                ")<1e-9 ? $4 : NaN) with linespoints lw 2 title \"" + kModes[i].name + "\"";
    }
    script += "\n";
  }
  script += "unset multiplot\n";
  return c.finish(t, script, findings,
                  static_cast<int>(450 * std::max<std::size_t>(1, ratios.size())), 520);
}

nlohmann::json sweep_rounds(Context& c) {
  const auto ratios = c.grid("inlier-ratio");
  constexpr double kPoints = 3000;
  CsvTable t({"mode", "inlier_ratio", "mean_rounds", "eq_2_7_rounds", "robustness"});
  nlohmann::json findings;
  for (double ratio : ratios) {
    std::vector<dsp::LabelledCloud> scenes;
    for (std::uint64_t seed : c.seeds()) scenes.push_back(sparse_scene(kPoints, ratio, seed));
    for (const Mode& m : kModes) {
      TrialSetup s = m.setup(c.threshold(0.05));
      std::vector<double> rounds;
      dsp::Robustness r;
      for (std::size_t k = 0; k < scenes.size(); ++k) {
        s.seed = c.seeds()[k];
        const TrialResult tr = c.trial(scenes[k], s);
        rounds.push_back(tr.rounds);
        r.add(tr.success);
      }
      const double theory =
          dsp::rounds_needed(std::pow(ratio, m.two_d ? 2 : 3), s.confidence, s.max_rounds);
      t.add(m.name).add(ratio).add(mean(rounds)).add(theory).add(r.value());
      t.end_row();
      findings[m.name].push_back({{"inlier_ratio", ratio},
                                  {"mean_rounds", mean(rounds)},
                                  {"eq_2_7_rounds", theory},
                                  {"robustness", r.value()}});
    }
    c.note("ratio " + num(ratio) + " done");
  }
  std::string script =
      "set title \"Rounds taken vs eq. 2.7 (p = 0.99; 3,000-point sparse map; min 200 rounds)\"\n"
      "set logscale y\nset xlabel \"wall fraction of the points (inlier ratio)\"\n"
      "set ylabel \"rounds\"\nset grid\nset key top right\nset logscale x\nplot ";
  const char* theory[] = {"3d-uniform", "2d-uniform"};
  for (const char* th : theory) {
    script += std::string("\"rounds.csv\" skip 1 using 2:(strcol(1) eq \"") + th +
              "\" ? $4 : NaN) with lines dt 2 lw 2 title \"eq. 2.7, " + (th[0] == '3' ? "3" : "2") +
              "-point samples\", ";
  }
  for (std::size_t i = 0; i < std::size(kModes); ++i) {
    script += std::string(i ? ", " : "") + "\"rounds.csv\" skip 1 using 2:(strcol(1) eq \"" +
              kModes[i].name + "\" ? $3 : NaN) with linespoints lw 2 title \"" + kModes[i].name +
              " (taken)\"";
  }
  script += "\n";
  return c.finish(t, script, findings);
}

nlohmann::json sweep_rho_estimate(Context& c) {
  const auto rhos = c.grid("rho-b");
  CsvTable t({"rho_b", "mean_estimate", "min_estimate", "max_estimate", "robustness"});
  nlohmann::json findings = nlohmann::json::array();
  for (double rho_b : rhos) {
    TrialSetup s;
    s.method = Method::kBinomial;
    s.rho = -1.0;
    s.threshold_m = c.threshold(0.1);
    std::vector<double> est;
    dsp::Robustness r;
    for (std::uint64_t seed : c.seeds()) {
      s.seed = seed;
      const TrialResult tr = c.trial(thesis_scene(c.options(), rho_b, seed), s);
      est.push_back(tr.rho_b);
      r.add(tr.success);
    }
    const auto [lo, hi] = std::minmax_element(est.begin(), est.end());
    t.add(rho_b).add(mean(est)).add(*lo).add(*hi).add(r.value());
    t.end_row();
    findings.push_back({{"rho_b", rho_b}, {"mean_estimate", mean(est)}, {"robustness", r.value()}});
  }
  const std::string script =
      "set title \"B-RANSAC's rho_b estimated from the data (BSF pass) vs the true rho_b\"\n"
      "set xlabel \"rho_b of the data\"\nset ylabel \"estimated rho_b\"\nset grid\n"
      "set key top left\nset xrange [0:1]\nset yrange [0:1]\nset y2label \"robustness\"\n"
      "set y2range [0:1.05]\nset y2tics\n"
      "plot x with lines dt 2 lc rgb \"gray\" title \"ideal\", \"rho-estimate.csv\" skip 1 "
      "using 1:2:3:4 with yerrorlines lw 2 title \"estimate (mean, min..max over seeds)\", \"\" "
      "skip 1 using 1:5 axes x1y2 with linespoints title \"B-RANSAC robustness with it\"\n";
  return c.finish(t, script, findings);
}

// Rounded to 12 significant digits, so that 0.1 * 3 is written as 0.3.
double round12(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.12g", v);
  return std::strtod(buf, nullptr);
}

}  // namespace

// ---- public -----------------------------------------------------------------------------------

std::vector<double> parse_range(std::string_view text, std::string_view flag) {
  std::vector<double> out;
  if (text.find(':') != std::string_view::npos) {
    const auto parts = split(text, ':');
    if (parts.size() != 3)
      flag_error(flag, "expects LO:HI:STEP or A,B,C, got '" + printable(text) + "'");
    const auto lo = to_double(parts[0]), hi = to_double(parts[1]), step = to_double(parts[2]);
    if (!lo || !hi || !step) {
      flag_error(flag, "expects numbers in LO:HI:STEP, got '" + printable(text) + "'");
    }
    if (!(*step > 0)) flag_error(flag, "step must be > 0, got '" + printable(text) + "'");
    if (*hi < *lo) flag_error(flag, "empty range: HI < LO in '" + printable(text) + "'");
    const double count = std::floor((*hi - *lo) / *step + 1e-9) + 1;
    if (count > static_cast<double>(kMaxGridValues)) {
      flag_error(flag, "more than 10000 values in '" + printable(text) + "'");
    }
    for (int i = 0; i < static_cast<int>(count); ++i) {
      const double v = *lo + i * *step;
      out.push_back(round12(v));
    }
  } else {
    for (std::string_view item : split(text, ',')) {
      const auto v = to_double(item);
      if (!v) flag_error(flag, "'" + printable(item) + "' is not a number");
      out.push_back(*v);
    }
    if (out.size() > kMaxGridValues) flag_error(flag, "more than 10000 values");
  }
  if (out.empty()) flag_error(flag, "empty range");
  return out;
}

std::vector<std::uint64_t> parse_seeds(std::string_view text) {
  std::vector<std::uint64_t> out;
  if (text.find('-') != std::string_view::npos) {
    const auto parts = split(text, '-');
    const auto a = parts.size() == 2 ? to_u64(parts[0]) : std::nullopt;
    const auto b = parts.size() == 2 ? to_u64(parts[1]) : std::nullopt;
    if (!a || !b) {
      flag_error("seeds",
                 "expects A-B or A,B,C of unsigned integers, got '" + printable(text) + "'");
    }
    if (*b < *a) flag_error("seeds", "empty range '" + printable(text) + "'");
    if (*b - *a >= kMaxSeeds) flag_error("seeds", "more than 100000 seeds");
    for (std::uint64_t s = *a; s <= *b; ++s) out.push_back(s);
    return out;
  }
  for (std::string_view item : split(text, ',')) {
    const auto v = to_u64(item);
    if (!v) flag_error("seeds", "'" + printable(item) + "' is not an unsigned integer");
    out.push_back(*v);
  }
  if (out.size() > kMaxSeeds) flag_error("seeds", "more than 100000 seeds");
  return out;
}

Method parse_method(std::string_view name) {
  for (Method m : {Method::kRansac, Method::kMsac, Method::kBsf, Method::kBinomial, Method::kPcl,
                   Method::kOpen3d}) {
    if (name == method_name(m)) {
      if ((m == Method::kPcl || m == Method::kOpen3d) && !peers_available()) {
        flag_error("methods", "'" + std::string(name) +
                                  "' is not in this build (PCL and Open3D are host-only; build "
                                  "with WALLAR_WITH_PEERS=ON)");
      }
      return m;
    }
  }
  flag_error("methods", "unknown method '" + printable(name) +
                            "' (known: ransac, msac, bsf, binomial, pcl, open3d)");
}

const char* method_name(Method m) {
  switch (m) {
    case Method::kRansac:
      return "ransac";
    case Method::kMsac:
      return "msac";
    case Method::kBsf:
      return "bsf";
    case Method::kBinomial:
      return "binomial";
    case Method::kPcl:
      return "pcl";
    case Method::kOpen3d:
      return "open3d";
  }
  return "?";
}

TrialResult run_trial(const dsp::LabelledCloud& scene, const TrialSetup& setup,
                      const dsp::SuccessCriterion& success) {
  TrialResult r;
  std::chrono::steady_clock::time_point t0;
  if (setup.method == Method::kPcl || setup.method == Method::kOpen3d) {
    t0 = std::chrono::steady_clock::now();
    const PeerFit f =
        fit_plane_peer(setup.method == Method::kPcl ? Peer::kPcl : Peer::kOpen3d, scene.cloud,
                       setup.threshold_m, setup.max_rounds, setup.confidence, setup.seed);
    r.found = f.found;
    r.plane = f.plane;
  } else {
    dsp::DetectorConfig cfg;
    cfg.method = score_of(setup.method);
    cfg.threshold_m = setup.threshold_m;
    cfg.beta = setup.beta;
    cfg.rho_b = setup.rho;
    cfg.confidence = setup.confidence;
    cfg.max_rounds = setup.max_rounds;
    cfg.seed = setup.seed;
    cfg.sampling = setup.sampling;
    dsp::WallDetector det(scene.cloud.size(), cfg);
    t0 = std::chrono::steady_clock::now();  // setup (allocation) is not the detection
    det.set_points(scene.cloud, setup.gravity);
    const dsp::Detection d = setup.gravity ? det.detect_vertical() : det.detect_3d();
    r.found = d.found;
    r.plane = d.plane;
    r.rounds = d.rounds;
    r.rounds_needed = d.rounds_needed;
    r.rho_b = d.rho_b;
  }
  r.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!r.found) return r;
  std::vector<Eigen::Vector3d> inliers;
  for (std::size_t i = 0; i < scene.cloud.size(); ++i) {
    const Eigen::Vector3d p = scene.cloud.point(i).cast<double>();
    if (std::abs(r.plane.signed_distance(p)) < setup.threshold_m) inliers.push_back(p);
  }
  r.inliers = static_cast<std::uint32_t>(inliers.size());
  r.rmse_m = dsp::projected_inlier_rmse(inliers, r.plane, scene.wall);
  r.error = dsp::plane_error(r.plane, scene.wall);
  r.success = success.success(r.error);
  return r;
}

const std::vector<std::string>& sweep_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& d : sweep_defs()) n.emplace_back(d.name);
    return n;
  }();
  return names;
}

std::vector<std::string> sweep_grids(std::string_view sweep) {
  std::vector<std::string> g;
  for (const auto& [flag, range] : find_sweep(sweep).grids) g.emplace_back(flag);
  return g;
}

void check_sweep(std::string_view name, const SweepOptions& options) {
  const SweepDef& def = find_sweep(name);
  for (const auto& grid : options.grids) {
    const std::string& flag = grid.first;  // not a structured binding: clang 14 cannot capture it
    const bool known = std::any_of(def.grids.begin(), def.grids.end(),
                                   [&](const auto& g) { return flag == g.first; });
    if (known) continue;
    std::string list;
    for (const auto& g : def.grids) list += std::string(list.empty() ? "--" : ", --") + g.first;
    flag_error(flag,
               std::string("does not apply to sweep '") + def.name + "' (it takes " + list + ")");
  }
}

nlohmann::json run_sweep(std::string_view name, const SweepOptions& options, OutputDir& out,
                         std::ostream* progress) {
  const SweepDef& def = find_sweep(name);
  Context c(def, options, out, progress);
  const std::string n(name);
  if (n == "bsf") return sweep_success_map(c, false);
  if (n == "binomial") return sweep_success_map(c, true);
  if (n == "threshold") return sweep_threshold(c);
  if (n == "gravity") return sweep_gravity(c);
  if (n == "runtime") return sweep_runtime(c);
  if (n == "rounds") return sweep_rounds(c);
  if (n == "rho-estimate") return sweep_rho_estimate(c);
  const SweepOptions& o = options;
  if (n == "methods") {
    return sweep_curves(
        c, "rho-b", methods_to_run(o),
        [&](double rho_b, std::uint64_t seed) { return thesis_scene(o, rho_b, seed); },
        "Robustness vs backliers on the thesis's scene (4.1)", "rho_b of the data");
  }
  // windows and clutter: the same curves over one count of the §4.1 scene.
  const bool windows = n == "windows";
  std::size_t dsp::ThesisSceneParams::*const count =
      windows ? &dsp::ThesisSceneParams::window_points : &dsp::ThesisSceneParams::clutter_points;
  const std::vector<Method> robust = {Method::kRansac, Method::kBsf, Method::kBinomial};
  return sweep_curves(
      c, windows ? "window-points" : "clutter-points", o.methods.empty() ? robust : o.methods,
      [&](double k, std::uint64_t seed) {
        dsp::ThesisSceneParams p = o.scene;
        p.*count = static_cast<std::size_t>(k);
        p.seed = seed;
        return dsp::make_thesis_scene(p);
      },
      (windows ? "A window in the wall: a patch of backliers (rho_b "
               : "Clutter: boxes between the front plane and the wall (rho_b ") +
          num(o.scene.rho_b) + ")",
      windows ? "points seen through the window" : "points on the boxes");
}

void write_labelled_scene(const dsp::LabelledCloud& scene, const std::filesystem::path& path) {
  const std::string ext = path.extension().string();
  std::string text;
  const std::size_t n = scene.cloud.size();
  char buf[160];
  if (ext == ".csv") {
    text = "x,y,z,label\n";
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f p = scene.cloud.point(i);
      std::snprintf(buf, sizeof buf, "%.6f,%.6f,%.6f,%s\n", static_cast<double>(p.x()),
                    static_cast<double>(p.y()), static_cast<double>(p.z()),
                    dsp::label_name(scene.labels[i]));
      text += buf;
    }
  } else if (ext == ".ply") {
    static constexpr std::uint8_t kColours[][3] = {{40, 110, 230},  {230, 140, 30}, {220, 40, 40},
                                                   {150, 150, 150}, {60, 180, 75},  {240, 220, 60},
                                                   {145, 30, 180},  {240, 50, 230}, {120, 90, 50}};
    text =
        "ply\nformat ascii 1.0\ncomment wallar eval synth; label: 0 wall, 1 front_plane, 2 "
        "backlier, 3 outlier, 4 floor, 5 ceiling, 6 other_wall, 7 window, 8 clutter\n";
    text += "element vertex " + std::to_string(n) +
            "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
            "property uchar green\nproperty uchar blue\nproperty uchar label\nend_header\n";
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f p = scene.cloud.point(i);
      const auto l = static_cast<std::size_t>(scene.labels[i]);
      const auto* c = kColours[std::min<std::size_t>(l, std::size(kColours) - 1)];
      std::snprintf(buf, sizeof buf, "%.6f %.6f %.6f %u %u %u %zu\n", static_cast<double>(p.x()),
                    static_cast<double>(p.y()), static_cast<double>(p.z()), c[0], c[1], c[2], l);
      text += buf;
    }
  } else {
    throw InputError(path.string() + ": unknown output format '" + printable(ext) +
                     "' (want .ply or .csv)");
  }
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  OutputDir(dir, false).write(path.filename().string(), text);
}

}  // namespace wallar::eval
