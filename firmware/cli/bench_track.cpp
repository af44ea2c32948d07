// SPDX-License-Identifier: Apache-2.0
/// @file bench_track.cpp
/// @brief `wallar bench track`: the tracker per stereo frame and the mapper per key-frame.
///
///  - track/frame/euroc_still: Tracker::track on the bundled EuRoC V1_01 still cut (752x480,
///    real images, the head at rest), frames played in order and looped;
///  - track/frame/synthetic_moving: the same on a rendered room flown through at 5 Hz (motion:
///    re-finding, key-frames with new points), 25 frames played forth and back;
///    counters: the mean of each stage per frame [ms] (rectify, pyramid, stage1, stage2,
///    keyframe) and tracks per frame;
///  - track/mapping/local_adjust: Mapper::add_keyframe + local_adjust of one key-frame of the
///    synthetic flight (a 6-key-frame window), per key-frame.
///
/// Threading: one thread (the tracker's budget is one core).
#if WALLAR_HAVE_BENCHMARK
#include <benchmark/benchmark.h>

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "bench_cases.hpp"
#include "wallar/core/time.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/jpeg.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/tracking/synthetic_room.hpp"
#include "wallar/dsp/tracking/tracker.hpp"

namespace wallar::cli {
namespace {

std::int64_t clock_ns() { return monotonic_now_ns(); }

struct Sequence {
  RigCalibration rig;
  std::vector<std::array<Image, 2>> pairs;
  std::vector<std::size_t> order;  // frames to play, looped
};

Sequence euroc_sequence(const std::string& recording) {
  const recording::EurocRecording rec = recording::read_euroc(recording);
  Sequence s;
  s.rig = rec.rig();
  const std::size_t n = std::min(rec.cams[0].frames.size(), rec.cams[1].frames.size());
  for (std::size_t i = 0; i < n; ++i) {
    s.pairs.push_back({recording::load_image_gray(rec.cams[0].image_path(rec.cams[0].frames[i])),
                       recording::load_image_gray(rec.cams[1].image_path(rec.cams[1].frames[i]))});
    s.order.push_back(i);
  }
  return s;
}

Sequence synthetic_sequence() {
  dsp::SyntheticRoom room;
  room.x_min_m = -2.0;
  room.x_max_m = 2.0;
  room.y_min_m = -2.5;
  room.y_max_m = 2.5;
  room.z_max_m = 2.5;
  const dsp::SyntheticCamera cam;
  Sequence s;
  for (CameraCalibration& c : s.rig.cams) {
    c.width_px = cam.width_px;
    c.height_px = cam.height_px;
    c.fx = c.fy = cam.f_px;
    c.cx = cam.cx_px;
    c.cy = cam.cy_px;
    c.distortion = {0.0, 0.0, 0.0, 0.0};
  }
  s.rig.cams[1].T_body_cam.translation() = Eigen::Vector3d(cam.baseline_m, 0.0, 0.0);
  const auto path = dsp::synthetic_trajectory(room, 25, 5.0);
  for (const StampedPose& p : path) {
    std::array<Image, 2> pair;
    for (int eye = 0; eye < 2; ++eye) {
      Image img = Image::allocate(cam.width_px, cam.height_px, PixelFormat::kGray8);
      dsp::render_room(room, cam, p.T_world_body, eye,
                       std::span<std::uint8_t>(img.mutable_data(),
                                               static_cast<std::size_t>(cam.width_px * cam.height_px)));
      pair[static_cast<std::size_t>(eye)] = img;
    }
    s.pairs.push_back(pair);
  }
  for (std::size_t i = 0; i < 25; ++i) s.order.push_back(i);
  for (std::size_t i = 23; i >= 1; --i) s.order.push_back(i);
  return s;
}

void bm_track(benchmark::State& state, const Sequence& seq) {
  dsp::Tracker tracker(seq.rig, dsp::TrackerConfig{}, &clock_ns);
  dsp::Mapper mapper(tracker.intrinsics());
  dsp::MapCorrection correction(20000, 256);
  dsp::TrackerTimes sum;
  double tracks = 0;
  std::size_t k = 0, frames = 0;
  for (auto _ : state) {
    const auto& pair = seq.pairs[seq.order[k % seq.order.size()]];
    const dsp::TrackResult r =
        tracker.track(static_cast<TimeNs>(k) * 50'000'000, pair[0], pair[1]);
    ++k;
    if (tracker.pending_keyframe() != nullptr) {
      state.PauseTiming();  // the mapping thread's work, not the tracker's
      mapper.add_keyframe(*tracker.pending_keyframe());
      mapper.local_adjust(correction);
      tracker.apply(correction);
      state.ResumeTiming();
    }
    sum.rectify_ns += r.times.rectify_ns;
    sum.pyramid_ns += r.times.pyramid_ns;
    sum.stage1_ns += r.times.stage1_ns;
    sum.stage2_ns += r.times.stage2_ns;
    sum.keyframe_ns += r.times.keyframe_ns;
    tracks += r.inliers;
    ++frames;
  }
  const auto ms = [frames](std::int64_t ns) {
    return static_cast<double>(ns) * 1e-6 / static_cast<double>(frames);
  };
  state.counters["rectify_ms"] = ms(sum.rectify_ns);
  state.counters["pyramid_ms"] = ms(sum.pyramid_ns);
  state.counters["stage1_ms"] = ms(sum.stage1_ns);
  state.counters["stage2_ms"] = ms(sum.stage2_ns);
  state.counters["keyframe_ms"] = ms(sum.keyframe_ns);
  state.counters["inliers"] = tracks / static_cast<double>(frames);
}

void bm_local_adjust(benchmark::State& state, const Sequence& seq) {
  // Record the key-frames of one pass, then time mapping them one by one.
  dsp::Tracker tracker(seq.rig, dsp::TrackerConfig{});
  std::vector<std::unique_ptr<dsp::KeyframeMessage>> keyframes;
  for (std::size_t k = 0; k < 25; ++k) {
    const auto& pair = seq.pairs[seq.order[k]];
    (void)tracker.track(static_cast<TimeNs>(k) * 200'000'000, pair[0], pair[1]);
    if (const dsp::KeyframeMessage* kf = tracker.pending_keyframe()) {
      auto copy = std::make_unique<dsp::KeyframeMessage>(kf->observations.capacity());
      copy->copy_from(*kf);
      keyframes.push_back(std::move(copy));
    }
  }
  dsp::MapCorrection correction(20000, 256);
  std::size_t adjusted = 0;
  for (auto _ : state) {
    state.PauseTiming();
    dsp::Mapper mapper(tracker.intrinsics());
    for (std::size_t i = 0; i + 1 < keyframes.size(); ++i) mapper.add_keyframe(*keyframes[i]);
    state.ResumeTiming();
    mapper.add_keyframe(*keyframes.back());
    const dsp::MapperStats s = mapper.local_adjust(correction);
    adjusted += static_cast<std::size_t>(s.adjusted_points);
  }
  state.counters["keyframes"] = static_cast<double>(keyframes.size());
  state.counters["points_adjusted"] =
      static_cast<double>(adjusted) / static_cast<double>(state.iterations());
}

std::string g_recording;

}  // namespace

void register_track_benchmarks() {
  static const Sequence euroc = euroc_sequence(g_recording);
  static const Sequence synthetic = synthetic_sequence();
  benchmark::RegisterBenchmark("track/frame/euroc_still",
                               [](benchmark::State& st) { bm_track(st, euroc); })
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("track/frame/synthetic_moving",
                               [](benchmark::State& st) { bm_track(st, synthetic); })
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("track/mapping/local_adjust",
                               [](benchmark::State& st) { bm_local_adjust(st, synthetic); })
      ->Unit(benchmark::kMillisecond);
}

void set_track_bench_recording(const std::string& recording) { g_recording = recording; }

}  // namespace wallar::cli
#endif  // WALLAR_HAVE_BENCHMARK
