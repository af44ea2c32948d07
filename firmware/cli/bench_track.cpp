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
///    synthetic flight (a 6-key-frame window), per key-frame;
///  - track/peer/opencv_frontend/{euroc_still,synthetic_moving}: the same per-frame work done
///    with OpenCV, as a user would assemble it: cv::remap of both images, cv::goodFeaturesToTrack
///    on the first frame, calcOpticalFlowPyrLK (11x11, 3 levels) of those corners frame to
///    frame, and solvePnPRansac (EPnP) of their first-frame stereo points (the peer of
///    stage 1; it has no stage 2, key-frames or relocalisation).
///
/// Threading: one thread (the tracker's budget is one core).
#if WALLAR_HAVE_BENCHMARK
#include <benchmark/benchmark.h>

#include <array>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <string>
#include <vector>

#include "bench_cases.hpp"
#include "wallar/core/time.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/jpeg.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/dsp/stereo/rectifier.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/tracking/synthetic_motion.hpp"
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
  const recording::EurocRecording rec = recording::read_recording(recording);
  Sequence s;
  s.rig = rec.rig();
  const std::size_t n = std::min(rec.cams[0].frames.size(), rec.cams[1].frames.size());
  for (std::size_t i = 0; i < n; ++i) {
    s.pairs.push_back({recording::load_frame_gray(rec, 0, rec.cams[0].frames[i]),
                       recording::load_frame_gray(rec, 1, rec.cams[1].frames[i])});
    s.order.push_back(i);
  }
  return s;
}

Sequence synthetic_sequence() {
  const dsp::SyntheticRoom room = dsp::small_room();
  const dsp::SyntheticCamera cam;
  Sequence s;
  s.rig = dsp::synthetic_rig(cam);
  const auto path = dsp::synthetic_trajectory(room, 25, 5.0);
  for (const StampedPose& p : path) {
    s.pairs.push_back({dsp::render_room_image(room, cam, p.T_world_body, 0),
                       dsp::render_room_image(room, cam, p.T_world_body, 1)});
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
    const dsp::TrackResult r = tracker.track(static_cast<TimeNs>(k) * 50'000'000, pair[0], pair[1]);
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
      auto copy = std::make_unique<dsp::KeyframeMessage>(kf->observations.capacity(),
                                                         kf->culled.capacity());
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

/// OpenCV doing stage 1's work: remap both eyes, LK of 300 corners, PnP RANSAC (EPnP).
void bm_opencv_frontend(benchmark::State& state, const Sequence& seq) {
  // One core, as the tracker: OpenCV's thread pool would otherwise split remap and LK.
  const int threads = cv::getNumThreads();
  cv::setNumThreads(1);
  const dsp::Rectifier rect(seq.rig);
  std::array<cv::Mat, 2> map1, map2;
  for (int cam = 0; cam < 2; ++cam) {
    cv::initUndistortRectifyMap(rect.K(cam), rect.dist(cam), rect.R(cam), rect.P(cam), rect.size(),
                                CV_16SC2, map1[static_cast<std::size_t>(cam)],
                                map2[static_cast<std::size_t>(cam)]);
  }
  const auto rectify = [&](const std::array<Image, 2>& pair, std::array<cv::Mat, 2>& out) {
    for (std::size_t cam = 0; cam < 2; ++cam) {
      cv::remap(dsp::wrap_gray(pair[cam]), out[cam], map1[cam], map2[cam], cv::INTER_LINEAR);
    }
  };
  // The first frame's corners and their stereo points (the "map").
  std::array<cv::Mat, 2> first;
  rectify(seq.pairs[seq.order[0]], first);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(first[0], corners, 300, 0.01, 10.0);
  std::vector<cv::Point2f> right_pts;
  std::vector<unsigned char> status;
  std::vector<float> error;
  cv::calcOpticalFlowPyrLK(first[0], first[1], corners, right_pts, status, error);
  std::vector<cv::Point3f> map;
  std::vector<cv::Point2f> tracked;
  const double fb = rect.f_px() * rect.baseline_m();
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const double d = corners[i].x - right_pts[i].x;
    if (status[i] == 0 || d < 1.0 || std::abs(corners[i].y - right_pts[i].y) > 1.0) continue;
    const double z = fb / d;
    map.emplace_back(static_cast<float>((corners[i].x - rect.cx()) * z / rect.f_px()),
                     static_cast<float>((corners[i].y - rect.cy()) * z / rect.f_px()),
                     static_cast<float>(z));
    tracked.push_back(corners[i]);
  }
  const cv::Matx33d K(rect.f_px(), 0, rect.cx(), 0, rect.f_px(), rect.cy(), 0, 0, 1);
  std::vector<cv::Mat> prev_pyr, cur_pyr;
  cv::buildOpticalFlowPyramid(first[0], prev_pyr, cv::Size(11, 11), 2);
  std::vector<cv::Point2f> prev = tracked, cur;
  cv::Mat rvec, tvec;
  std::size_t k = 1, inliers = 0;
  std::array<cv::Mat, 2> rectified;
  for (auto _ : state) {
    rectify(seq.pairs[seq.order[k % seq.order.size()]], rectified);
    ++k;
    cv::buildOpticalFlowPyramid(rectified[0], cur_pyr, cv::Size(11, 11), 2);
    cv::calcOpticalFlowPyrLK(prev_pyr, cur_pyr, prev, cur, status, error, cv::Size(11, 11), 2);
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    for (std::size_t i = 0; i < cur.size(); ++i) {
      if (status[i] == 0) continue;
      obj.push_back(map[i]);
      img.push_back(cur[i]);
    }
    std::vector<int> inl;
    if (obj.size() >= 6) {
      cv::solvePnPRansac(obj, img, K, cv::noArray(), rvec, tvec, false, 100, 2.0f, 0.99, inl,
                         cv::SOLVEPNP_EPNP);
    }
    inliers += inl.size();
    std::swap(prev_pyr, cur_pyr);
    prev = cur;  // the points keep their map index (lost ones stay lost: status 0 later too)
  }
  state.counters["inliers"] =
      static_cast<double>(inliers) / static_cast<double>(state.iterations());
  state.counters["map_points"] = static_cast<double>(map.size());
  cv::setNumThreads(threads);
}

std::string g_recording;

}  // namespace

void register_track_benchmarks() {
  static const Sequence euroc = euroc_sequence(g_recording);
  static const Sequence synthetic = synthetic_sequence();
  benchmark::RegisterBenchmark("track/frame/euroc_still", [](benchmark::State& st) {
    bm_track(st, euroc);
  })->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("track/frame/synthetic_moving", [](benchmark::State& st) {
    bm_track(st, synthetic);
  })->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("track/peer/opencv_frontend/euroc_still", [](benchmark::State& st) {
    bm_opencv_frontend(st, euroc);
  })->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("track/peer/opencv_frontend/synthetic_moving",
                               [](benchmark::State& st) { bm_opencv_frontend(st, synthetic); })
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("track/mapping/local_adjust", [](benchmark::State& st) {
    bm_local_adjust(st, synthetic);
  })->Unit(benchmark::kMillisecond);
}

void set_track_bench_recording(const std::string& recording) { g_recording = recording; }

}  // namespace wallar::cli
#endif  // WALLAR_HAVE_BENCHMARK
