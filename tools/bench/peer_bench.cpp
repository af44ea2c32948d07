// SPDX-License-Identifier: Apache-2.0
/// @file peer_bench.cpp
/// @brief wallar_peer_bench: our WallDetector against PCL 1.13 and Open3D on THE SAME clouds,
/// thresholds and rounds, in one run (Google Benchmark). Host only; see docs/perf.md.
///
/// throughput/<cloud>/<impl>: one plane search of exactly kRounds rounds per iteration.
///   - wallar_ransac: ScoreMethod::kRansac, Sampling::kUniform, min_rounds = max_rounds = R,
///     no local optimisation, no viewpoint/facing checks (every sample is scored).
///   - pcl_plane: pcl::SACSegmentation<PointXYZ>, SACMODEL_PLANE + SAC_RANSAC,
///     setMaxIterations(R), setProbability(1) (no early stop), setOptimizeCoefficients(false).
///     (PCL's loop scores R + 1 samples and does not count degenerate ones.)
///   - open3d: PointCloud::SegmentPlane(t, 3, R, probability 1) (no early stop; it always ends
///     with a least-squares refit and one more inlier pass).
///   - wallar_ransac_2d / pcl_parallel_plane: with gravity (clouds in the camera frame, gravity
///     +y). PCL's model for "plane containing the axis" (a wall, normal perpendicular to
///     gravity) is SACMODEL_PARALLEL_PLANE; SACMODEL_PERPENDICULAR_PLANE keeps planes whose
///     NORMAL is along the axis (floors, ceilings) and is run too, to show that.
///   Counters: time_per_round [s], point_tests_per_s (points * rounds / CPU time), inliers.
/// success/<scenes>/<impl>: one detection per iteration over the scenes of seeds 1..kSeeds;
///   counters success_pct (normal within 5 deg and offset within 0.1 m of scene.wall) and
///   front_plane_pct (thesis scenes: the decoy plane was chosen instead).
///
/// Open3D's RANSAC is an OpenMP loop: main() pins OMP_NUM_THREADS=1 (re-executing itself so
/// that libgomp, which reads it at load time, sees it) and omp_set_num_threads(1). PCL's
/// SAC_RANSAC runs single-threaded unless setNumberOfThreads() asks otherwise.
#include <benchmark/benchmark.h>
#include <omp.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <open3d/geometry/PointCloud.h>
#include <open3d/utility/Random.h>
#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/common/io.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>
#include <string>
#include <vector>

#include "wallar/dsp/walls/plane_kernel.hpp"
#include "wallar/dsp/walls/synthetic.hpp"
#include "wallar/dsp/walls/wall_detector.hpp"

namespace {

using wallar::Plane;
using wallar::PointCloud;
namespace dsp = wallar::dsp;

constexpr int kRounds = 1000;        // R: rounds of every throughput case and of the peers' success runs
constexpr std::uint64_t kSeeds = 50; // scenes per success case
const Eigen::Vector3d kGravity(0.0, 9.81, 0.0);
constexpr double kEpsAngleRad = 5.0 * M_PI / 180.0;

// ---- clouds, in the three libraries' layouts ---------------------------------------------------

struct Cloud {
  std::string name;
  double threshold = 0.0;
  bool has_gravity = false;  // camera frame, gravity +y (synthetic scenes only)
  PointCloud ours;
  pcl::PointCloud<pcl::PointXYZ>::Ptr pcl;
  std::shared_ptr<open3d::geometry::PointCloud> o3d;
  Plane wall;        // ground truth (synthetic scenes)
  Plane front;       // thesis scenes: the decoy plane in front of the wall
};

Cloud make_cloud(std::string name, const PointCloud& pts, double threshold, bool has_gravity) {
  Cloud c;
  c.name = std::move(name);
  c.threshold = threshold;
  c.has_gravity = has_gravity;
  c.ours = pts;
  c.pcl.reset(new pcl::PointCloud<pcl::PointXYZ>);
  c.o3d = std::make_shared<open3d::geometry::PointCloud>();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    c.pcl->push_back(pcl::PointXYZ(pts.x[i], pts.y[i], pts.z[i]));
    c.o3d->points_.emplace_back(pts.x[i], pts.y[i], pts.z[i]);
  }
  return c;
}

Cloud sparse_map(std::uint64_t seed) {
  dsp::SparseMapParams p;  // 2000 points, 3.5 % wall
  p.seed = seed;
  const auto s = dsp::make_sparse_map(p);
  Cloud c = make_cloud("sparse_map_2000", s.cloud, 0.03, true);
  c.wall = s.wall;
  return c;
}

Cloud thesis_scene(std::uint64_t seed) {
  dsp::ThesisSceneParams p;  // the thesis's defaults
  p.seed = seed;
  const auto s = dsp::make_thesis_scene(p);
  Cloud c = make_cloud("thesis_scene", s.cloud, 0.1, true);
  c.wall = s.wall;
  c.front = Plane{-Eigen::Vector3d::UnitZ(), -p.plane_distance_m};
  return c;
}

std::optional<Cloud> pcl_reference_cloud() {
  const std::string path = WALLAR_PCL_REFERENCE_CLOUD;
  if (!std::filesystem::exists(path)) return std::nullopt;
  pcl::PointCloud<pcl::PointXYZ> in;
  if (pcl::io::loadPCDFile<pcl::PointXYZ>(path, in) != 0) return std::nullopt;
  PointCloud pts;
  for (const auto& p : in) pts.push_back(Eigen::Vector3f(p.x, p.y, p.z));
  return make_cloud("pcl_sac_plane_test", pts, 0.03, false);  // PCL's test: 0.03 m
}

const std::vector<Cloud>& throughput_clouds() {
  static const std::vector<Cloud> clouds = [] {
    std::vector<Cloud> v{sparse_map(1), thesis_scene(1)};
    if (auto ref = pcl_reference_cloud()) v.push_back(std::move(*ref));
    return v;
  }();
  return clouds;
}

// ---- the implementations: each returns the plane found (front toward the origin) ---------------

struct Found {
  bool found = false;
  Plane plane;
  std::size_t inliers = 0;
};

enum class Impl {
  kWallarRansac,    // like-for-like: kRansac, uniform, fixed R, no LO, no checks
  kWallarRansac2d,  // the same on the ground plane (detect_vertical)
  kWallarBsf,       // our default: BSF, guided, adaptive rounds, LO (3-D)
  kWallarBsf2d,     // our default in 2-D
  kWallarBinomial,  // B-RANSAC, rho_b estimated
  kPclPlane,
  kPclParallelPlane,
  kPclPerpendicularPlane,
  kOpen3d,
};

dsp::DetectorConfig wallar_config(Impl impl, double threshold, std::uint64_t seed) {
  dsp::DetectorConfig cfg;
  cfg.threshold_m = threshold;
  cfg.seed = seed;
  if (impl == Impl::kWallarRansac || impl == Impl::kWallarRansac2d) {
    cfg.method = dsp::ScoreMethod::kRansac;
    cfg.sampling = dsp::Sampling::kUniform;
    cfg.min_rounds = cfg.max_rounds = kRounds;
    cfg.local_optimisation_iterations = 0;
    cfg.facing_check = false;
    cfg.min_viewpoint_distance_m = 0.0;
  } else if (impl == Impl::kWallarBinomial) {
    cfg.method = dsp::ScoreMethod::kBinomial;
  }
  return cfg;
}

bool is_wallar(Impl impl) {
  return impl == Impl::kWallarRansac || impl == Impl::kWallarRansac2d ||
         impl == Impl::kWallarBsf || impl == Impl::kWallarBsf2d || impl == Impl::kWallarBinomial;
}
bool is_2d(Impl impl) {
  return impl == Impl::kWallarRansac2d || impl == Impl::kWallarBsf2d;
}

Plane from_coefficients(double a, double b, double c, double d) {
  const Eigen::Vector3d n(a, b, c);
  const double len = n.norm();
  Plane p{n / len, -d / len};  // a x + b y + c z + d = 0  <=>  n.p = -d
  return p.facing(Eigen::Vector3d::Zero());
}

// One runner per benchmark: holds what each library keeps between calls.
class Runner {
 public:
  Runner(Impl impl, const Cloud& c, std::uint64_t seed, bool fixed_rounds)
      : impl_(impl), cloud_(c) {
    if (is_wallar(impl)) {
      det_ = std::make_unique<dsp::WallDetector>(c.ours.size(), wallar_config(impl, c.threshold, seed));
    } else if (impl != Impl::kOpen3d) {
      seg_.setOptimizeCoefficients(!fixed_rounds);
      seg_.setModelType(impl == Impl::kPclPlane           ? pcl::SACMODEL_PLANE
                        : impl == Impl::kPclParallelPlane ? pcl::SACMODEL_PARALLEL_PLANE
                                                          : pcl::SACMODEL_PERPENDICULAR_PLANE);
      seg_.setMethodType(pcl::SAC_RANSAC);
      seg_.setMaxIterations(kRounds);
      seg_.setDistanceThreshold(c.threshold);
      if (fixed_rounds) seg_.setProbability(1.0);  // k = log(0)/log(.) = inf: no early stop
      if (impl != Impl::kPclPlane) {
        seg_.setAxis(kGravity.normalized().cast<float>());
        seg_.setEpsAngle(kEpsAngleRad);
      }
      seg_.setInputCloud(c.pcl);
    }
    o3d_probability_ = fixed_rounds ? 1.0 : 0.99999999;  // Open3D's default otherwise
  }

  Found run() {
    Found f;
    if (det_) {
      dsp::Detection d;
      if (is_2d(impl_)) {
        det_->set_points(cloud_.ours, kGravity);
        d = det_->detect_vertical();
      } else {
        det_->set_points(cloud_.ours);
        d = det_->detect_3d();
      }
      f.found = d.found;
      f.plane = d.plane;
      f.inliers = d.inliers;
      rounds_ = d.rounds;
    } else if (impl_ == Impl::kOpen3d) {
      const auto [model, inliers] =
          cloud_.o3d->SegmentPlane(cloud_.threshold, 3, kRounds, o3d_probability_);
      f.found = !inliers.empty();
      if (f.found) f.plane = from_coefficients(model[0], model[1], model[2], model[3]);
      f.inliers = inliers.size();
      rounds_ = kRounds;
    } else {
      seg_.segment(pcl_inliers_, pcl_coeffs_);
      f.found = pcl_coeffs_.values.size() == 4 && !pcl_inliers_.indices.empty();
      if (f.found) {
        const auto& v = pcl_coeffs_.values;
        f.plane = from_coefficients(v[0], v[1], v[2], v[3]);
      }
      f.inliers = pcl_inliers_.indices.size();
      rounds_ = kRounds;
    }
    return f;
  }
  [[nodiscard]] std::uint32_t rounds() const { return rounds_; }

 private:
  Impl impl_;
  const Cloud& cloud_;
  std::unique_ptr<dsp::WallDetector> det_;
  pcl::SACSegmentation<pcl::PointXYZ> seg_;
  pcl::PointIndices pcl_inliers_;
  pcl::ModelCoefficients pcl_coeffs_;
  double o3d_probability_ = 1.0;
  std::uint32_t rounds_ = 0;
};

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}
bool is_plane(const Found& f, const Plane& truth) {
  return f.found && angle_deg(f.plane.n, truth.n) < 5.0 && std::abs(f.plane.d - truth.d) < 0.1;
}

// ---- benchmarks ----------------------------------------------------------------------------

void bm_throughput(benchmark::State& state, Impl impl, std::size_t cloud_index) {
  const Cloud& c = throughput_clouds()[cloud_index];
  open3d::utility::random::Seed(1);
  Runner r(impl, c, 1, true);
  Found f;
  std::uint64_t rounds = 0;
  for (auto _ : state) {
    f = r.run();
    rounds += r.rounds();
    benchmark::DoNotOptimize(f);
  }
  const double per_iter = static_cast<double>(rounds) / static_cast<double>(state.iterations());
  state.counters["time_per_round"] = benchmark::Counter(
      per_iter, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["point_tests_per_s"] = benchmark::Counter(
      per_iter * static_cast<double>(c.ours.size()), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["points"] = static_cast<double>(c.ours.size());
  state.counters["inliers"] = static_cast<double>(f.inliers);
}

const std::vector<Cloud>& scenes(bool thesis) {
  static const std::vector<Cloud> thesis_scenes = [] {
    std::vector<Cloud> v;
    for (std::uint64_t s = 1; s <= kSeeds; ++s) v.push_back(thesis_scene(s));
    return v;
  }();
  static const std::vector<Cloud> sparse_maps = [] {
    std::vector<Cloud> v;
    for (std::uint64_t s = 1; s <= kSeeds; ++s) v.push_back(sparse_map(s));
    return v;
  }();
  return thesis ? thesis_scenes : sparse_maps;
}

// Iteration i: scene (and detector seed) i + 1. Peers use R rounds in their usual setup
// (PCL: probability 0.99 and coefficient refinement; Open3D: its default probability).
void bm_success(benchmark::State& state, Impl impl, bool thesis) {
  const auto& v = scenes(thesis);
  open3d::utility::random::Seed(1);
  std::vector<std::unique_ptr<Runner>> runners;
  for (std::uint64_t s = 1; s <= kSeeds; ++s) {
    runners.push_back(std::make_unique<Runner>(impl, v[s - 1], s, false));
  }
  std::uint64_t i = 0, wall = 0, front = 0, rounds = 0;
  for (auto _ : state) {
    const std::size_t k = i++ % kSeeds;
    const Found f = runners[k]->run();
    benchmark::DoNotOptimize(f);
    wall += is_plane(f, v[k].wall) ? 1 : 0;
    front += thesis && is_plane(f, v[k].front) ? 1 : 0;
    rounds += runners[k]->rounds();
  }
  const auto n = static_cast<double>(std::max<std::uint64_t>(i, 1));
  state.counters["success_pct"] = 100.0 * static_cast<double>(wall) / n;
  if (thesis) state.counters["front_plane_pct"] = 100.0 * static_cast<double>(front) / n;
  state.counters["mean_rounds"] = static_cast<double>(rounds) / n;
}

const char* impl_name(Impl impl) {
  switch (impl) {
    case Impl::kWallarRansac: return "wallar_ransac";
    case Impl::kWallarRansac2d: return "wallar_ransac_2d";
    case Impl::kWallarBsf: return "wallar_bsf";
    case Impl::kWallarBsf2d: return "wallar_bsf_2d";
    case Impl::kWallarBinomial: return "wallar_bransac";
    case Impl::kPclPlane: return "pcl_plane";
    case Impl::kPclParallelPlane: return "pcl_parallel_plane";
    case Impl::kPclPerpendicularPlane: return "pcl_perpendicular_plane";
    case Impl::kOpen3d: return "open3d";
  }
  return "?";
}

void register_benchmarks() {
  const auto& clouds = throughput_clouds();
  for (std::size_t ci = 0; ci < clouds.size(); ++ci) {
    std::vector<Impl> impls{Impl::kWallarRansac, Impl::kPclPlane, Impl::kOpen3d};
    if (clouds[ci].has_gravity) {
      impls.insert(impls.end(), {Impl::kWallarRansac2d, Impl::kPclParallelPlane,
                                 Impl::kPclPerpendicularPlane});
    }
    for (Impl impl : impls) {
      const std::string name = "throughput/" + clouds[ci].name + "/" + impl_name(impl);
      benchmark::RegisterBenchmark(name.c_str(), [impl, ci](benchmark::State& st) {
        bm_throughput(st, impl, ci);
      })->Unit(benchmark::kMicrosecond);
    }
  }
  for (const bool thesis : {true, false}) {
    std::vector<Impl> impls{Impl::kWallarRansac, Impl::kWallarBsf, Impl::kWallarBinomial,
                            Impl::kPclPlane, Impl::kOpen3d};
    if (!thesis) {
      impls.insert(impls.end(), {Impl::kWallarRansac2d, Impl::kWallarBsf2d,
                                 Impl::kPclParallelPlane});
    }
    for (Impl impl : impls) {
      const std::string name = std::string("success/") +
                               (thesis ? "thesis_scene" : "sparse_map_2000") + "/" + impl_name(impl);
      benchmark::RegisterBenchmark(name.c_str(), [impl, thesis](benchmark::State& st) {
        bm_success(st, impl, thesis);
      })->Iterations(static_cast<benchmark::IterationCount>(kSeeds))->Unit(benchmark::kMicrosecond);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  // One thread for Open3D's OpenMP loop: libgomp reads OMP_NUM_THREADS when it is loaded,
  // before main, so set it and start again; omp_set_num_threads covers a failed exec.
  const char* omp = std::getenv("OMP_NUM_THREADS");
  if (omp == nullptr || std::string(omp) != "1") {
    setenv("OMP_NUM_THREADS", "1", 1);
    execv("/proc/self/exe", argv);
  }
  omp_set_num_threads(1);
  pcl::console::setVerbosityLevel(pcl::console::L_ERROR);

  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  benchmark::AddCustomContext("omp_max_threads", std::to_string(omp_get_max_threads()));
  benchmark::AddCustomContext("plane_kernel_target", dsp::plane_kernel_target());
  benchmark::AddCustomContext("rounds_R", std::to_string(kRounds));
  register_benchmarks();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
