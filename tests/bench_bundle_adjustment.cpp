// SPDX-License-Identifier: Apache-2.0
/// @file bench_bundle_adjustment.cpp
/// @brief Local bundle adjustment as the mapping thread runs it: 10 keyframes (the 2 oldest
/// fixed), 1500 points each seen in stereo by 6 consecutive keyframes, poses perturbed by
/// 2 cm / 1 deg and points by 5 cm, 0.5 px noise, default options (Google Benchmark).
///
/// Threading: benchmark thread only.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "wallar/dsp/tracking/bundle_adjustment.hpp"

namespace {

using namespace wallar;
using namespace wallar::dsp;

constexpr double kPi = 3.14159265358979323846;

// Doubles from raw mt19937_64 outputs.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(gen_() >> 11) * 0x1.0p-53;
  }
  double gaussian() {  // Box-Muller
    const double u1 = 1.0 - uniform(0, 1), u2 = uniform(0, 1);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
  }
  Eigen::Vector3d direction() {
    return Eigen::Vector3d(gaussian(), gaussian(), gaussian()).normalized();
  }

 private:
  std::mt19937_64 gen_;
};

struct LocalWindow {
  std::vector<BaKeyframe> keyframes;
  std::vector<BaPoint> points;
  std::vector<BaObservation> observations;
};

const StereoIntrinsics kRig{535.0, 320.0, 240.0, 0.12};

// A camera walking 15 cm to the right per keyframe with a slight yaw, looking along +z.
LocalWindow make_window(std::uint64_t seed) {
  Rng rng(seed);
  constexpr int kKeyframes = 10, kPoints = 1500, kSpan = 6;
  LocalWindow w;
  std::vector<SE3d> truth;
  for (int k = 0; k < kKeyframes; ++k) {
    SE3d T_world_cam = SE3d::Identity();
    T_world_cam.linear() = Eigen::AngleAxisd(0.02 * (k - 5), Eigen::Vector3d::UnitY()).matrix();
    T_world_cam.translation() = Eigen::Vector3d(0.15 * k, 0.02 * (k % 2), 0.05 * k);
    truth.push_back(T_world_cam.inverse());
  }
  for (int p = 0; p < kPoints; ++p) {
    // Seen by keyframes first .. first + 5: created in the middle one's image, 1.5 - 6 m deep.
    const int first = p % (kKeyframes - kSpan + 1);
    const SE3d& T_mid = truth[static_cast<std::size_t>(first + kSpan / 2)];
    const double z = rng.uniform(1.5, 6.0);
    const Eigen::Vector3d p_cam((rng.uniform(40, 600) - kRig.cx_px) * z / kRig.f_px,
                                (rng.uniform(40, 440) - kRig.cy_px) * z / kRig.f_px, z);
    const Eigen::Vector3d p_world = T_mid.inverse() * p_cam;
    w.points.push_back({p_world + 0.05 * rng.direction(), false});
    for (int k = first; k < first + kSpan; ++k) {
      const Eigen::Vector3d q = truth[static_cast<std::size_t>(k)] * p_world;
      BaObservation o;
      o.keyframe = k;
      o.point = p;
      o.u_px = kRig.f_px * q.x() / q.z() + kRig.cx_px + 0.5 * rng.gaussian();
      o.v_px = kRig.f_px * q.y() / q.z() + kRig.cy_px + 0.5 * rng.gaussian();
      o.u_right_px =
          kRig.f_px * (q.x() - kRig.baseline_m) / q.z() + kRig.cx_px + 0.5 * rng.gaussian();
      w.observations.push_back(o);
    }
  }
  for (int k = 0; k < kKeyframes; ++k) {
    BaKeyframe kf{truth[static_cast<std::size_t>(k)], k < 2};
    if (!kf.fixed) {
      SE3d D = SE3d::Identity();
      D.linear() = Eigen::AngleAxisd(kPi / 180.0, rng.direction()).matrix();
      D.translation() = 0.02 * rng.direction();
      kf.T_cam_world = D * kf.T_cam_world;
    }
    w.keyframes.push_back(kf);
  }
  return w;
}

void BM_LocalBundleAdjustment(benchmark::State& state) {
  const LocalWindow start = make_window(42);
  BaResult result;
  for (auto _ : state) {
    state.PauseTiming();
    LocalWindow w = start;
    state.ResumeTiming();
    result = bundle_adjust(kRig, w.keyframes, w.points, w.observations);
    benchmark::DoNotOptimize(result);
  }
  state.counters["observations"] = static_cast<double>(start.observations.size());
  state.counters["iterations"] = result.iterations;
  state.counters["cost_ratio"] = result.initial_cost / result.final_cost;
  state.counters["converged"] = result.converged ? 1 : 0;
}
BENCHMARK(BM_LocalBundleAdjustment)->Unit(benchmark::kMillisecond);

}  // namespace
