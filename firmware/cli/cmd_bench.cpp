// SPDX-License-Identifier: Apache-2.0
/// @file cmd_bench.cpp
/// @brief `wallar bench walls`: Google Benchmark cases of wall detection, run in-process, so the
/// figures come from the very binary that ships (and run on the board, or under qemu).
///
///  - walls/kernel/{simd,scalar}/N: dsp::score_plane (run-time dispatched SIMD) and the scalar
///    reference on an in-cache cloud of N points; counters items_per_second (point-tests) and
///    ns_per_point_test; the label names the SIMD target.
///  - walls/detect_{3d,2d}/{guided,uniform}: set_points + detect_3d / detect_vertical on
///    dsp::make_sparse_map (2000 points, 3.5 % wall), one detection per iteration over the
///    scenes of seeds 1..kSeeds; counters success_pct (normal within 5 deg and offset within
///    0.1 m of the scene's wall) and mean_rounds.
///  - walls/room_{3d,2d}/family: what `wallar walls` runs (dsp::RoomEstimator with the
///    command's defaults: threshold 5 cm, up to 6 surfaces) on kSeeds scenes drawn at random
///    from dsp::sparse_map_family (seeds from --family-seed; wall fraction 2 - 10 %, tilt
///    0 - 20 deg, a cabinet in half, clumped clutter in half, a second wall in a corner in
///    half); counters success_pct (every wall of the scene among the surfaces),
///    spurious_per_scene (surfaces on no true plane), mean_surfaces and median_ms, p90_ms,
///    max_ms (each scene's time); .../surface_sigma_4: the same with the opt-in band test
///    (`wallar walls --surface-sigma 4`); .../contrast: with `--method contrast`.
///  - `wallar bench imu`: imu/attitude_update{,_mag}: one dsp::AttitudeFilter::update() on a
///    200 Hz stream of a turning body (target: under 1 us).
///  - `wallar bench track`: the tracker and mapper (bench_track.cpp).
///
/// Google Benchmark flags pass through after `--`; `--json FILE` writes JSON to FILE.
/// Builds without Google Benchmark (WALLAR_BUILD_BENCH=OFF: the asan, tsan and fuzz presets) keep
/// the command, which then says so and fails.
///
/// Threading: the benchmarks run on the calling thread (one core).
#if WALLAR_HAVE_BENCHMARK
#include <benchmark/benchmark.h>
#include <unistd.h>
#endif

#include <hwy/targets.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bench_cases.hpp"
#include "commands.hpp"
#include "wallar/dsp/imu/attitude_filter.hpp"
#include "wallar/dsp/walls/plane_kernel.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/dsp/walls/synthetic.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"

namespace wallar::cli {
namespace {

struct BenchArgs {
  std::string json;
  std::vector<std::string> passthrough;
  std::string recording = "tests/data/euroc_v1_01_still";
  std::uint64_t family_seed = 1;  //!< the room benchmarks' first scene of the family
};

#if WALLAR_HAVE_BENCHMARK

constexpr std::uint64_t kSeeds = 50;             // scenes per detection benchmark
constexpr double kSparseThreshold = 0.03;        // as tests/unit/test_walls.cpp
const Eigen::Vector3d kGravity(0.0, 9.81, 0.0);  // the scenes' camera frame: y is down

// ---- (a) the kernel -------------------------------------------------------------------------

struct KernelCloud {
  std::vector<float> x, y, z;
  std::vector<Eigen::Vector4f> planes;  // (nx, ny, nz, d), cycled so no call is repeated
};

KernelCloud make_kernel_cloud(std::size_t n) {
  KernelCloud c;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  c.x.resize(n);
  c.y.resize(n);
  c.z.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    c.x[i] = u(rng);
    c.y[i] = u(rng);
    c.z[i] = u(rng);
  }
  for (int i = 0; i < 64; ++i) {
    const Eigen::Vector3f nrm = Eigen::Vector3f(u(rng), u(rng), u(rng)).normalized();
    c.planes.emplace_back(nrm.x(), nrm.y(), nrm.z(), u(rng) / 3.0f);
  }
  return c;
}

template <bool kSimd>
void bm_kernel(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));  // a multiple of kPointPadding
  const KernelCloud c = make_kernel_cloud(n);
  std::size_t k = 0;
  std::uint64_t sink = 0;
  for (auto _ : state) {
    const Eigen::Vector4f& p = c.planes[k++ & 63u];
    const dsp::PlaneCounts r = kSimd ? dsp::score_plane(c.x.data(), c.y.data(), c.z.data(), n, p[0],
                                                        p[1], p[2], p[3], 0.05f)
                                     : dsp::score_plane_scalar(c.x.data(), c.y.data(), c.z.data(),
                                                               n, p[0], p[1], p[2], p[3], 0.05f);
    sink += r.inliers + r.backliers;
    benchmark::DoNotOptimize(sink);
  }
  const auto points = static_cast<double>(n);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(n));
  // CPU time / (points * iterations), in ns: an inverted iteration-invariant rate of points.
  state.counters["ns_per_point_test"] = benchmark::Counter(
      points * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.SetLabel(kSimd ? dsp::plane_kernel_target() : "scalar");
}

// ---- (b), (c) whole detections ----------------------------------------------------------------

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

/// The success criterion of every wall benchmark: normal within 5 deg, offset within 0.1 m.
bool same_plane(const Plane& a, const Plane& b) {
  return angle_deg(a.n, b.n) < 5.0 && std::abs(a.d - b.d) < 0.1;
}

bool is_wall(const dsp::Detection& d, const Plane& truth) {
  return d.found && same_plane(d.plane, truth);
}

const std::vector<dsp::LabelledCloud>& sparse_maps() {
  static const std::vector<dsp::LabelledCloud> scenes = [] {
    std::vector<dsp::LabelledCloud> s;
    for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
      dsp::SparseMapParams p;  // 2000 points, 3.5 % wall, rho_b 0.1
      p.seed = seed;
      s.push_back(dsp::make_sparse_map(p));
    }
    return s;
  }();
  return scenes;
}

// One iteration = one detection (set_points, then detect: the neighbour grid is rebuilt each
// time, as for a new map). Iteration i uses scene and detector seed i % kSeeds + 1; the
// benchmark runs a multiple of kSeeds iterations, so every scene counts the same.
void bm_detect(benchmark::State& state, bool two_d, dsp::Sampling sampling) {
  const auto& scenes = sparse_maps();
  std::vector<std::unique_ptr<dsp::WallDetector>> detectors;
  for (std::uint64_t seed = 1; seed <= kSeeds; ++seed) {
    dsp::DetectorConfig cfg;  // the default: BSF, guided, LO, 99 % confidence
    cfg.threshold_m = kSparseThreshold;
    cfg.sampling = sampling;
    cfg.seed = seed;
    detectors.push_back(std::make_unique<dsp::WallDetector>(scenes[seed - 1].cloud.size(), cfg));
  }
  std::uint64_t found = 0, rounds = 0, i = 0;
  for (auto _ : state) {
    const auto s = static_cast<std::size_t>(i++ % kSeeds);
    dsp::WallDetector& det = *detectors[s];
    dsp::Detection d;
    if (two_d) {
      det.set_points(scenes[s].cloud, kGravity);
      d = det.detect_vertical();
    } else {
      det.set_points(scenes[s].cloud);
      d = det.detect_3d();
    }
    benchmark::DoNotOptimize(d);
    found += is_wall(d, scenes[s].wall) ? 1 : 0;
    rounds += d.rounds;
  }
  const auto n = static_cast<double>(std::max<std::uint64_t>(i, 1));
  state.counters["success_pct"] = 100.0 * static_cast<double>(found) / n;
  state.counters["mean_rounds"] = static_cast<double>(rounds) / n;
  state.counters["scenes"] = static_cast<double>(std::min<std::uint64_t>(i, kSeeds));
}

// ---- (d) the walls command over the scene family -------------------------------------------

std::uint64_t g_family_seed = 1;  // set before the benchmarks run (--family-seed)

const std::vector<dsp::LabelledCloud>& family_maps() {
  static const std::vector<dsp::LabelledCloud> scenes = [] {
    std::vector<dsp::LabelledCloud> s;
    for (std::uint64_t seed = g_family_seed; seed < g_family_seed + kSeeds; ++seed) {
      s.push_back(dsp::make_sparse_map(dsp::sparse_map_family(seed)));
    }
    return s;
  }();
  return scenes;
}

// One iteration = one `wallar walls` estimate of scene i % kSeeds (its points loaded, every
// surface searched, then the search that finds none).
void bm_room(benchmark::State& state, bool two_d, double surface_sigma, bool contrast) {
  const auto& scenes = family_maps();
  std::size_t most = 0;
  for (const auto& sc : scenes) most = std::max(most, sc.cloud.size());
  dsp::RoomEstimator room(most);
  std::uint64_t found = 0, spurious = 0, surfaces = 0, i = 0;
  std::vector<double> scene_ms;  // each estimate's wall time: the target is the median
  scene_ms.reserve(static_cast<std::size_t>(state.max_iterations));
  for (auto _ : state) {
    const auto s = static_cast<std::size_t>(i++ % kSeeds);
    dsp::RoomConfig cfg;  // the walls command's defaults
    cfg.detector.threshold_m = 0.05;
    cfg.detector.seed = s + 1;
    cfg.min_excess_sigma = surface_sigma;
    if (contrast) cfg.detector.method = dsp::ScoreMethod::kContrast;
    if (two_d) cfg.gravity = 9.81 * scenes[s].down;
    const TimeNs t0_ns = monotonic_now_ns();
    const dsp::RoomResult r = room.estimate(scenes[s].cloud, cfg);
    scene_ms.push_back(static_cast<double>(monotonic_now_ns() - t0_ns) * 1e-6);
    benchmark::DoNotOptimize(r);
    // Success: every wall of the scene found (the wall, and the side wall where there is one).
    bool wall = true;
    for (const Plane& truth : scenes[s].all_walls) {
      bool seen = false;
      for (const Wall& w : r.model.walls) seen |= same_plane(w.plane, truth);
      wall &= seen;
    }
    for (const Wall& w : r.model.walls) {
      bool on_truth = false;
      for (const Plane& t : scenes[s].surfaces) on_truth |= same_plane(w.plane, t);
      spurious += on_truth ? 0 : 1;
    }
    found += wall ? 1 : 0;
    surfaces += r.model.walls.size();
  }
  const auto n = static_cast<double>(std::max<std::uint64_t>(i, 1));
  state.counters["success_pct"] = 100.0 * static_cast<double>(found) / n;
  if (!scene_ms.empty()) {
    std::sort(scene_ms.begin(), scene_ms.end());
    state.counters["median_ms"] = scene_ms[scene_ms.size() / 2];
    state.counters["p90_ms"] = scene_ms[scene_ms.size() * 9 / 10];
    state.counters["max_ms"] = scene_ms.back();
  }
  state.counters["spurious_per_scene"] = static_cast<double>(spurious) / n;
  state.counters["mean_surfaces"] = static_cast<double>(surfaces) / n;
  state.counters["scenes"] = static_cast<double>(std::min<std::uint64_t>(i, kSeeds));
}

void register_wall_benchmarks() {
  for (const std::int64_t n : {2048, 16384}) {
    benchmark::RegisterBenchmark("walls/kernel/simd", bm_kernel<true>)->Arg(n);
    benchmark::RegisterBenchmark("walls/kernel/scalar", bm_kernel<false>)->Arg(n);
  }
  // Each SIMD target this CPU runs (e.g. AVX-512, AVX2, SSE4 on x86-64), forced one at a time,
  // so the AVX2 figure exists on a machine that would dispatch to AVX-512.
  for (const std::int64_t target : hwy::SupportedAndGeneratedTargets()) {
    const std::string name = std::string("walls/kernel/target/") + hwy::TargetName(target);
    benchmark::RegisterBenchmark(name.c_str(), [target](benchmark::State& st) {
      hwy::SetSupportedTargetsForTest(target);
      bm_kernel<true>(st);
      hwy::SetSupportedTargetsForTest(0);  // back to the CPU's best
    })->Arg(2048);
  }
  struct Case {
    const char* name;
    bool two_d;
    dsp::Sampling sampling;
    std::int64_t iterations;
  };
  // Guided runs take about a millisecond and uniform 3-D ones tens: 4 rounds over the 50
  // scenes, or one.
  const Case cases[] = {{"walls/detect_3d/guided", false, dsp::Sampling::kGuided, 4 * kSeeds},
                        {"walls/detect_2d/guided", true, dsp::Sampling::kGuided, 4 * kSeeds},
                        {"walls/detect_3d/uniform", false, dsp::Sampling::kUniform, kSeeds},
                        {"walls/detect_2d/uniform", true, dsp::Sampling::kUniform, 4 * kSeeds}};
  for (const Case& c : cases) {
    benchmark::RegisterBenchmark(c.name,
                                 [c](benchmark::State& st) { bm_detect(st, c.two_d, c.sampling); })
        ->Iterations(c.iterations)
        ->Unit(benchmark::kMicrosecond);
  }
  // The defaults (BSF), BSF with the band test, and the contrast score.
  struct Variant {
    const char* suffix;
    double sigma;
    bool contrast;
  };
  for (const Variant v : {Variant{"", 0.0, false}, Variant{"/surface_sigma_4", 4.0, false},
                          Variant{"/contrast", 0.0, true}}) {
    for (const bool two_d : {false, true}) {
      const std::string name =
          std::string(two_d ? "walls/room_2d/family" : "walls/room_3d/family") + v.suffix;
      benchmark::RegisterBenchmark(
          name.c_str(),
          [two_d, v](benchmark::State& st) { bm_room(st, two_d, v.sigma, v.contrast); })
          ->Iterations(kSeeds)
          ->Unit(benchmark::kMicrosecond);
    }
  }
}

// ---- (e) the attitude filter ------------------------------------------------------------------

// One iteration = one AttitudeFilter::update() (gyro propagation + accelerometer update) on a
// precomputed 200 Hz stream of a body turning with a gyro bias; the stream cycles, with its
// timestamps shifted on so time keeps increasing. With a magnetometer adds the heading update.
void bm_attitude_update(benchmark::State& state, bool with_mag) {
  constexpr std::size_t kSamples = 4096;
  std::vector<ImuSample> samples(kSamples);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  for (std::size_t i = 0; i < kSamples; ++i) {
    const double t_s = static_cast<double>(i) / 200.0;
    ImuSample& s = samples[i];
    s.t_ns = static_cast<TimeNs>(i) * 5 * kNsPerMs;
    s.gyro_rad_s = Eigen::Vector3d(0.5 * std::sin(0.7 * t_s), 0.4 * std::cos(0.5 * t_s), 0.02) +
                   Eigen::Vector3d(u(rng), u(rng), u(rng));
    s.accel_m_s2 = Eigen::Vector3d(u(rng), u(rng), 9.81 + u(rng));
    if (with_mag) s.mag_uT = Eigen::Vector3d(24.0 + u(rng), u(rng), -41.6);
  }
  dsp::AttitudeFilter filter;
  dsp::StaticImuEstimate still;
  still.mean_accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.81);
  filter.initialize(still, -5 * kNsPerMs);
  std::size_t i = 0;
  TimeNs offset_ns = 0;
  for (auto _ : state) {
    ImuSample s = samples[i];
    s.t_ns += offset_ns;
    benchmark::DoNotOptimize(filter.update(s));
    if (++i == kSamples) {
      i = 0;
      offset_ns += static_cast<TimeNs>(kSamples) * 5 * kNsPerMs;
    }
  }
  benchmark::DoNotOptimize(filter.q_world_imu());
  state.counters["updates_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void register_imu_benchmarks() {
  benchmark::RegisterBenchmark("imu/attitude_update",
                               [](benchmark::State& st) { bm_attitude_update(st, false); });
  benchmark::RegisterBenchmark("imu/attitude_update_mag",
                               [](benchmark::State& st) { bm_attitude_update(st, true); });
}

// The console shows ns_per_point_test in the label: as a counter it would be printed as if in
// seconds. The JSON file (a separate reporter) keeps the counter as it is.
class ConsoleWithNs final : public benchmark::ConsoleReporter {
 public:
  using ConsoleReporter::ConsoleReporter;
  void ReportRuns(const std::vector<Run>& runs) override {
    std::vector<Run> shown = runs;
    for (Run& r : shown) {
      const auto it = r.counters.find("ns_per_point_test");
      if (it == r.counters.end()) continue;
      char buf[64];
      std::snprintf(buf, sizeof buf, " %.3f ns/point-test", static_cast<double>(it->second));
      r.report_label += buf;
      r.counters.erase(it);
    }
    ConsoleReporter::ReportRuns(shown);
  }
};

int run_bench(const BenchArgs& args, const std::string& name, void (*register_cases)()) {
  std::vector<std::string> flags{"wallar bench " + name};
  if (!args.json.empty()) {
    flags.push_back("--benchmark_out=" + args.json);
    flags.push_back("--benchmark_out_format=json");
  }
  bool console = true;
  for (const std::string& a : args.passthrough) {
    flags.push_back(a);
    if (a.rfind("--benchmark_format=", 0) == 0 && a != "--benchmark_format=console")
      console = false;
  }
  std::vector<char*> argv;
  for (std::string& f : flags) argv.push_back(f.data());
  argv.push_back(nullptr);
  int argc = static_cast<int>(flags.size());
  benchmark::Initialize(&argc, argv.data());
  if (benchmark::ReportUnrecognizedArguments(argc, argv.data())) return kExitUsage;
  benchmark::AddCustomContext("plane_kernel_target", dsp::plane_kernel_target());
  register_cases();
  ConsoleWithNs display(isatty(STDOUT_FILENO) ? benchmark::ConsoleReporter::OO_Color
                                              : benchmark::ConsoleReporter::OO_None);
  const std::size_t ran = benchmark::RunSpecifiedBenchmarks(console ? &display : nullptr);
  benchmark::Shutdown();
  if (ran == 0) {
    std::fprintf(stderr, "wallar: error: no benchmark matched the filter\n");
    return kExitUsage;
  }
  return kExitOk;
}

int run_bench_walls(const BenchArgs& args) {
  g_family_seed = args.family_seed;
  return run_bench(args, "walls", register_wall_benchmarks);
}
int run_bench_imu(const BenchArgs& args) { return run_bench(args, "imu", register_imu_benchmarks); }
int run_bench_track(const BenchArgs& args) {
  set_track_bench_recording(args.recording);
  return run_bench(args, "track", register_track_benchmarks);
}

#else  // !WALLAR_HAVE_BENCHMARK

int run_bench_imu(const BenchArgs& /*args*/) {
  std::fprintf(stderr,
               "wallar: error: this build has no benchmarks (configured with "
               "WALLAR_BUILD_BENCH=OFF)\n");
  return kExitFailure;
}

int run_bench_track(const BenchArgs& /*args*/) {
  std::fprintf(stderr,
               "wallar: error: this build has no benchmarks (configured with "
               "WALLAR_BUILD_BENCH=OFF)\n");
  return kExitFailure;
}

int run_bench_walls(const BenchArgs& /*args*/) {
  std::fprintf(stderr,
               "wallar: error: this build has no benchmarks (configured with "
               "WALLAR_BUILD_BENCH=OFF)\n");
  return kExitFailure;
}

#endif  // WALLAR_HAVE_BENCHMARK

}  // namespace

void add_bench_command(CLI::App& app, std::function<int()>& run) {
  CLI::App* bench = app.add_subcommand("bench", "Benchmarks of the hot paths (Google Benchmark)");
  bench->require_subcommand(1);
  auto args = std::make_shared<BenchArgs>();
  CLI::App* walls = bench->add_subcommand(
      "walls",
      "Wall detection: plane kernel (SIMD vs scalar), 3-D and 2-D detection on a sparse "
      "map, guided vs uniform sampling");
  walls
      ->add_option("--json", args->json,
                   "Also write the results as JSON to FILE (--benchmark_out=FILE "
                   "--benchmark_out_format=json)")
      ->option_text("FILE");
  walls
      ->add_option("--family-seed", args->family_seed,
                   "First of the 50 scenes of the family the walls/room benchmarks draw (another "
                   "value: scenes the defaults were not chosen on)")
      ->capture_default_str();
  walls->add_option("benchmark_flags", args->passthrough,
                    "Google Benchmark flags, after --, e.g. -- --benchmark_filter=kernel");
  walls->callback([args, &run] { run = [args] { return run_bench_walls(*args); }; });
  CLI::App* imu = bench->add_subcommand(
      "imu", "Attitude filter: one update (gyro propagation + accelerometer [+ magnetometer])");
  imu->add_option("--json", args->json,
                  "Also write the results as JSON to FILE (--benchmark_out=FILE "
                  "--benchmark_out_format=json)")
      ->option_text("FILE");
  imu->add_option("benchmark_flags", args->passthrough,
                  "Google Benchmark flags, after --, e.g. -- --benchmark_min_time=2");
  imu->callback([args, &run] { run = [args] { return run_bench_imu(*args); }; });
  CLI::App* track = bench->add_subcommand(
      "track",
      "Tracking per 752x480 stereo frame (with a per-stage breakdown) and mapping per key-frame");
  track->add_option("--recording", args->recording,
                    "EuRoC recording for the real-image case (default: the bundled still cut, "
                    "relative to the current folder)");
  track
      ->add_option("--json", args->json,
                   "Also write the results as JSON to FILE (--benchmark_out=FILE "
                   "--benchmark_out_format=json)")
      ->option_text("FILE");
  track->add_option("benchmark_flags", args->passthrough,
                    "Google Benchmark flags, after --, e.g. -- --benchmark_repetitions=5");
  track->callback([args, &run] { run = [args] { return run_bench_track(*args); }; });
}

}  // namespace wallar::cli
