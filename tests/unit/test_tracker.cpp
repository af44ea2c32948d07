// SPDX-License-Identifier: Apache-2.0
/// @file test_tracker.cpp
/// @brief The stereo tracker and mapper: its parts (corners, row matching, Lucas-Kanade, pose),
/// a rendered room flown through on a known path, the real EuRoC still sequence, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <thread>
#include <utility>
#include <vector>

#include "test_support.hpp"
#include "tracking_support.hpp"
#include "wallar/core/error.hpp"
#include "wallar/core/hash.hpp"
#include "wallar/core/spsc_ring.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/jpeg.hpp"
#include "wallar/dsp/eval/trajectory.hpp"
#include "wallar/dsp/tracking/features.hpp"
#include "wallar/dsp/tracking/klt.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/tracking/pose_estimation.hpp"
#include "wallar/dsp/tracking/synthetic_room.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/dsp/walls/room_check.hpp"
#include "wallar/firmware/offline.hpp"
#include "wallar/firmware/tracking_and_mapping.hpp"

namespace wallar {
namespace {

using dsp::SyntheticCamera;
using dsp::SyntheticRoom;

using dsp::synthetic_rig;

Image render(const SyntheticRoom& room, const SyntheticCamera& c, const SE3d& T_world_cam,
             int cam) {
  return dsp::render_room_image(room, c, T_world_cam, cam);
}

Image filled(int width, int height, std::uint8_t value) {
  Image img = Image::allocate(width, height, PixelFormat::kGray8);
  std::fill_n(img.mutable_data(), static_cast<std::size_t>(width * height), value);
  return img;
}

using test::gray_view;

// --- Parts -------------------------------------------------------------------------------------

TEST(TrackerParts, CornersAreSpreadOverBucketsAndCapped) {
  const SyntheticRoom room = test::small_room();
  const SyntheticCamera cam;
  const auto path = dsp::synthetic_trajectory(room, 1, 10.0);
  const Image img = render(room, cam, path[0].T_world_body, 0);
  dsp::DetectorParams params;
  params.bucket_px = 48;
  params.per_bucket = 3;
  dsp::CornerDetector detector(cam.width_px, cam.height_px, params);
  std::vector<std::uint16_t> occupancy(static_cast<std::size_t>(detector.bucket_count()), 0);
  occupancy[0] = 3;  // a bucket already full of tracks gets nothing new
  dsp::FixedVector<dsp::Corner> corners(2000);
  detector.detect(gray_view(img), occupancy, corners);
  std::vector<int> per_bucket(static_cast<std::size_t>(detector.bucket_count()), 0);
  for (const dsp::Corner& c : corners)
    ++per_bucket[static_cast<std::size_t>(detector.bucket_of(c.u_px, c.v_px))];
  EXPECT_EQ(per_bucket[0], 0);
  EXPECT_LE(*std::max_element(per_bucket.begin(), per_bucket.end()), 3);
  const auto filled_buckets =
      std::count_if(per_bucket.begin(), per_bucket.end(), [](int n) { return n > 0; });
  EXPECT_GT(filled_buckets, detector.bucket_count() * 3 / 4);
  for (const dsp::Corner& c : corners) EXPECT_GE(c.shi_tomasi, params.min_shi_tomasi);
}

TEST(TrackerParts, TheThresholdAdaptsToABlankImage) {
  const Image blank = filled(320, 240, 128);
  dsp::CornerDetector detector(320, 240, dsp::DetectorParams{});
  std::vector<std::uint16_t> occupancy(static_cast<std::size_t>(detector.bucket_count()), 0);
  dsp::FixedVector<dsp::Corner> corners(100);
  const int before = detector.threshold();
  for (int i = 0; i < 10; ++i) detector.detect(gray_view(blank), occupancy, corners);
  EXPECT_TRUE(corners.empty());
  EXPECT_LT(detector.threshold(), before);
  EXPECT_EQ(detector.threshold(), dsp::DetectorParams{}.threshold_min);
}

TEST(TrackerParts, RowMatchingRecoversTheRenderedDisparity) {
  const SyntheticRoom room = test::small_room();
  const SyntheticCamera cam;
  const SE3d T = dsp::synthetic_trajectory(room, 1, 10.0)[0].T_world_body;
  const Image left = render(room, cam, T, 0), right = render(room, cam, T, 1);
  const dsp::FixedVector<dsp::Corner> corners = test::detect_corners(left, 500);
  int matched = 0, close = 0;
  for (const dsp::Corner& c : corners) {
    const auto d =
        dsp::match_along_row(gray_view(left), gray_view(right), c.u_px, c.v_px, 2, 120, {});
    if (!d) continue;
    ++matched;
    // Truth: the depth along the pixel's ray.
    const Eigen::Vector3d ray((c.u_px - cam.cx_px) / cam.f_px, (c.v_px - cam.cy_px) / cam.f_px,
                              1.0);
    const auto hit = dsp::ray_hit(room, T.translation(), T.linear() * ray);
    ASSERT_TRUE(hit.has_value());
    const double truth = cam.f_px * cam.baseline_m / hit->range;
    close += std::abs(*d - truth) < 0.5 ? 1 : 0;
  }
  EXPECT_GT(matched, static_cast<int>(corners.size()) / 2);
  EXPECT_GT(close, matched * 9 / 10);  // corners sit where depth may jump: most, not all
}

// A feature on the lowest row the matcher accepts: the sub-pixel refinement's 9x9 window then
// ends on the image's last row, and a bilinear sample there must not read the row below it
// (outside the buffer: ASan saw it on the street clip, 1344x372, in CI's sanitizer stage).
TEST(TrackerParts, RowMatchingOnTheLastRowsStaysInsideTheImage) {
  constexpr int kW = 160, kH = 40, kShift = 7;
  // Exactly-sized buffers, so a read past the last row is outside the allocation.
  std::vector<std::uint8_t> left(static_cast<std::size_t>(kW * kH)), right(left.size());
  std::uint64_t state = 12345;
  std::vector<std::uint8_t> texture(static_cast<std::size_t>((kW + kShift) * kH));
  for (std::uint8_t& t : texture) t = static_cast<std::uint8_t>(core::splitmix64_next(state) >> 56);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      left[static_cast<std::size_t>(y * kW + x)] =
          texture[static_cast<std::size_t>(y * (kW + kShift) + x)];
      right[static_cast<std::size_t>(y * kW + x)] =
          texture[static_cast<std::size_t>(y * (kW + kShift) + x + kShift)];
    }
  }
  const dsp::GrayView l{left.data(), kW, kH, kW}, r{right.data(), kW, kH, kW};
  const dsp::StereoMatchParams params;
  const int lowest = kH - params.half_window - 2;  // match_along_row's own limit
  int matched = 0;
  for (int v = lowest - 2; v <= lowest; ++v) {
    for (float u = 40.0f; u < 120.0f; u += 10.0f) {
      const auto d = dsp::match_along_row(l, r, u, static_cast<float>(v), 2, 30, params);
      if (!d) continue;
      ++matched;
      // A texel at x in the left image is at x - kShift in the right: disparity kShift.
      EXPECT_NEAR(*d, static_cast<float>(kShift), 0.3f) << "v " << v << " u " << u;
    }
  }
  EXPECT_GT(matched, 10);
}

TEST(TrackerParts, LucasKanadeFollowsAKnownShift) {
  const SyntheticRoom room = test::small_room();
  const SyntheticCamera cam;
  const SE3d T0 = dsp::synthetic_trajectory(room, 1, 10.0)[0].T_world_body;
  // The right image is the left seen 0.11 m to the right: a pure horizontal disparity.
  const Image left = render(room, cam, T0, 0), right = render(room, cam, T0, 1);
  dsp::Pyramid prev(cam.width_px, cam.height_px, 3), cur(cam.width_px, cam.height_px, 3);
  prev.build(gray_view(left));
  cur.build(gray_view(right));
  // Lucas-Kanade is meant for corners: track the detector's.
  const dsp::FixedVector<dsp::Corner> corners = test::detect_corners(left, 300);
  int ok = 0, good = 0;
  for (const dsp::Corner& c : corners) {
    float u = c.u_px, v = c.v_px;  // no guess: a 15-40 px shift for the pyramid to find
    if (!dsp::klt_track(prev, cur, c.u_px, c.v_px, u, v)) continue;
    ++ok;
    const Eigen::Vector3d ray((c.u_px - cam.cx_px) / cam.f_px, (c.v_px - cam.cy_px) / cam.f_px,
                              1.0);
    const auto hit = dsp::ray_hit(room, T0.translation(), T0.linear() * ray);
    const double d = cam.f_px * cam.baseline_m / hit->range;
    good += std::abs((c.u_px - u) - d) < 0.3 && std::abs(v - c.v_px) < 0.3 ? 1 : 0;
  }
  // Translation-only windows on slanted walls seen from 11 cm apart: most, not all.
  EXPECT_GE(ok, static_cast<int>(corners.size()) * 3 / 5);
  EXPECT_GT(good, ok * 4 / 5);
}

TEST(TrackerParts, PoseFromStereoObservationsWithOutliers) {
  const dsp::StereoIntrinsics K{450.0, 376.0, 240.0, 0.11};
  SE3d T = SE3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, 1.0, 0.1).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.3, -0.1, 0.2);
  std::vector<dsp::PoseObservation> obs;
  std::uint64_t s = 12345;
  const auto uniform = [&s] {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(s >> 11) * (1.0 / 9007199254740992.0);
  };
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p_cam((uniform() - 0.5) * 4.0, (uniform() - 0.5) * 3.0,
                                1.0 + 5.0 * uniform());
    dsp::PoseObservation o;
    o.p_world = T.inverse() * p_cam;
    const Eigen::Vector3d uvr = K.project(p_cam);
    const bool outlier = i % 3 == 0;  // a third are wrong by 5-40 px
    const double e = outlier ? 5.0 + 35.0 * uniform() : 0.3 * (uniform() - 0.5);
    o.u_px = static_cast<float>(uvr.x() + e);
    o.v_px = static_cast<float>(uvr.y() - e);
    o.u_right_px = i % 5 == 1 ? NAN : static_cast<float>(uvr.z() + e);
    obs.push_back(o);
  }
  std::vector<std::uint8_t> inlier(obs.size());
  const auto check = [&](const dsp::PoseResult& r, const char* what) {
    ASSERT_TRUE(r.ok) << what;
    EXPECT_LT((r.T_cam_world.translation() - T.translation()).norm(), 0.01) << what;
    EXPECT_LT(Eigen::AngleAxisd(r.T_cam_world.linear() * T.linear().transpose()).angle(), 0.002)
        << what;
    int wrong = 0;
    for (std::size_t i = 0; i < obs.size(); ++i) wrong += (inlier[i] != 0) == (i % 3 == 0) ? 1 : 0;
    EXPECT_LE(wrong, 4) << what;
  };
  // A prediction a few pixels off (a bump the motion model did not foresee: 2 cm, 1.5 deg, so
  // hardly any observation is within the inlier radius of it): the wide pass pulls it in.
  SE3d near = T;
  near.translation() += Eigen::Vector3d(0.02, 0.0, 0.0);
  near.linear() =
      Eigen::AngleAxisd(0.026, Eigen::Vector3d::UnitX()).toRotationMatrix() * near.linear();
  check(dsp::estimate_pose(K, obs, near, inlier, 7), "prior 1.5 deg off");
  // A prior looking the other way (30 cm, 160 deg: every point behind it): only RANSAC can find
  // the pose.
  SE3d prior = T;
  prior.translation() += Eigen::Vector3d(0.3, 0.0, 0.0);
  prior.linear() =
      prior.linear() * Eigen::AngleAxisd(2.8, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const dsp::PoseResult r = dsp::estimate_pose(K, obs, prior, inlier, 7);
  EXPECT_TRUE(r.from_ransac);
  check(r, "prior 160 deg off");
}

TEST(TrackerParts, SpscRingPassesEverySlotInOrderBetweenTwoThreads) {
  SpscRing<std::vector<int>> ring(8, [] { return std::vector<int>(16, 0); });
  constexpr int kMessages = 20000;
  std::thread producer([&] {
    for (int i = 0; i < kMessages; ++i) {
      std::vector<int>* slot = nullptr;
      while ((slot = ring.producer_slot()) == nullptr) std::this_thread::yield();
      for (int& v : *slot) v = i;  // the slot is written in place, never reallocated
      ring.push();
    }
  });
  int expected = 0;
  bool in_order = true;
  while (expected < kMessages) {
    std::vector<int>* slot = ring.front();
    if (slot == nullptr) {
      std::this_thread::yield();
      continue;
    }
    for (int v : *slot) in_order = in_order && v == expected;
    ring.pop();
    ++expected;
  }
  producer.join();
  EXPECT_TRUE(in_order);
  EXPECT_EQ(ring.size_approx(), 0u);
}

TEST(TrackerMap, PointsHiddenBehindAnOccluderAreCulledAndTheMapperForgetsThem) {
  // The camera holds still; from frame 1 on, a dark board hides the left 60 % of both images.
  // The map points behind it are predicted in view frame after frame and never found; the
  // last frame hides 85 %, so few tracks remain and a key-frame carries the news to the mapper.
  const SyntheticRoom room = test::small_room();
  const SyntheticCamera cam;
  const SE3d T = dsp::synthetic_trajectory(room, 1, 10.0)[0].T_world_body;
  const Image left = render(room, cam, T, 0), right = render(room, cam, T, 1);
  const auto occluded = [&](const Image& src, int percent) {
    Image out = Image::allocate(cam.width_px, cam.height_px, PixelFormat::kGray8);
    std::copy_n(src.data(), static_cast<std::size_t>(cam.width_px * cam.height_px),
                out.mutable_data());
    for (int y = 0; y < cam.height_px; ++y) {
      std::fill_n(out.mutable_data() + std::ptrdiff_t{y} * cam.width_px,
                  cam.width_px * percent / 100, 20);
    }
    return out;
  };
  dsp::TrackerConfig config;
  config.max_tracks = 400;  // more than the visible part can hold: stage 2 keeps looking
  dsp::Tracker tracker(synthetic_rig(cam), config);
  dsp::Mapper mapper(tracker.intrinsics());
  dsp::MapCorrection correction(20000, 256);
  std::size_t culled_told = 0;
  for (int k = 0; k <= 60; ++k) {
    const int percent = k == 0 ? 0 : k < 60 ? 60 : 85;
    const dsp::TrackResult r =
        tracker.track(k * 100'000'000LL, occluded(left, percent), occluded(right, percent));
    ASSERT_EQ(r.state, dsp::TrackingState::kTracking) << "frame " << k;
    if (const dsp::KeyframeMessage* kf = tracker.pending_keyframe()) {
      culled_told += kf->culled.size();
      mapper.add_keyframe(*kf);
      mapper.local_adjust(correction);
      tracker.apply(correction);
    }
  }
  // The points of the first key-frame behind the 60 % board (u < 0.55 width, safely inside).
  std::size_t hidden_alive = 0, hidden_dead = 0;
  for (const dsp::MapPoint& p : tracker.map_points()) {
    if (p.keyframe != 0) continue;
    const Eigen::Vector3d uvr = tracker.intrinsics().project(p.p_world);  // world = first camera
    if (uvr.x() >= cam.width_px * 0.55) continue;
    (p.alive ? hidden_alive : hidden_dead) += 1;
  }
  EXPECT_GT(hidden_dead, 100u);
  EXPECT_LT(hidden_alive, hidden_dead / 10);
  EXPECT_GE(culled_told, hidden_dead);  // the mapper heard of each one
  const dsp::MapSnapshot map = mapper.snapshot();
  std::size_t hidden_in_map = 0;
  for (std::size_t i = 0; i < map.points.size(); ++i) {
    hidden_in_map +=
        tracker.intrinsics().project(map.points.point(i).cast<double>()).x() < cam.width_px * 0.55
            ? 1
            : 0;
  }
  EXPECT_LE(hidden_in_map, hidden_alive);
}

// --- A rendered room on a known path ------------------------------------------------------------

struct SyntheticRun {
  std::vector<StampedPose> truth, estimate;  // T_world_cam, both in the room's frame
  std::shared_ptr<const dsp::MapSnapshot> map;
  int lost = 0;
};

SyntheticRun fly_through_room(int frames, double rate_hz) {
  const SyntheticRoom room = test::small_room();
  const SyntheticCamera cam;
  firmware::TrackingOptions options;
  options.mapping_thread = false;  // lock step: repeatable
  options.use_gyro = false;
  firmware::TrackingAndMapping system(synthetic_rig(cam), options);
  SyntheticRun run;
  run.truth = dsp::synthetic_trajectory(room, frames, rate_hz);
  const SE3d T_world0 = run.truth.front().T_world_body;  // the tracker's world: the first camera
  for (const StampedPose& p : run.truth) {
    const dsp::TrackResult r = system.on_stereo(test::stereo(room, cam, p.T_world_body, p.t_ns));
    run.lost += r.state == dsp::TrackingState::kTracking ? 0 : 1;
    run.estimate.push_back(StampedPose{p.t_ns, T_world0 * r.T_world_cam});
  }
  run.map = system.finish();
  // Poses after the last global adjustment are not re-reported; the map is (in the same frame).
  return run;
}

/// Set by CMake when the tests run under an emulator (qemu): fewer rendered frames.
using test::short_tests;

TEST(TrackerSynthetic, FollowsAKnownPathThroughARenderedRoom) {
  // 10 s, half of the loop (under an emulator 4 s: 0.85 m).
  const SyntheticRun run = fly_through_room(short_tests() ? 20 : 50, 5.0);
  EXPECT_EQ(run.lost, 0);
  dsp::TrajectoryEvalOptions eo;
  eo.max_dt_ns = 1'000'000;
  const dsp::TrajectoryErrors e = dsp::evaluate_trajectory(run.estimate, run.truth, eo);
  std::printf("synthetic: path %.3f m, ATE %.4f m (%.3f %%), max %.4f m, RPE %.4f m / %.3f deg\n",
              e.path_length_m, e.ate_rmse_m, 100.0 * e.ate_rmse_m / e.path_length_m, e.ate_max_m,
              e.rpe_trans_rmse_m, e.rpe_rot_rmse_deg);
  EXPECT_GT(e.path_length_m, short_tests() ? 0.6 : 1.5);
  EXPECT_LT(e.ate_rmse_m, 0.01 * e.path_length_m);
  ASSERT_TRUE(run.map != nullptr);
  // The map's points lie on the room's surfaces.
  const SyntheticRoom room = test::small_room();
  const SE3d T_world0 = run.truth.front().T_world_body;
  std::vector<double> distance;
  for (std::size_t i = 0; i < run.map->points.size(); ++i) {
    distance.push_back(
        room.distance_to_nearest_surface(T_world0 * run.map->points.point(i).cast<double>()));
  }
  ASSERT_GT(distance.size(), short_tests() ? 300u : 500u);
  std::sort(distance.begin(), distance.end());
  const double median = distance[distance.size() / 2];
  const double p90 = distance[distance.size() * 9 / 10];
  std::printf(
      "synthetic map: %zu points, distance to the true surfaces: median %.4f m, 90%% %.4f m\n",
      distance.size(), median, p90);
  EXPECT_LT(median, 0.01);
  EXPECT_LT(p90, 0.03);
}

TEST(TrackerSynthetic, GlobalAdjustmentsRunOnTheConfiguredScheduleInLockStep) {
  // Off by default: only the one at the end. Every third key-frame when asked, corrections
  // applied at once, so lock step stays repeatable either way.
  const SyntheticRoom room = test::small_room();
  const SyntheticCamera cam;
  const std::vector<StampedPose> path = dsp::synthetic_trajectory(room, 20, 5.0);
  std::vector<StereoFrame> frames;
  for (const StampedPose& p : path)
    frames.push_back(test::stereo(room, cam, p.T_world_body, p.t_ns));
  const auto run = [&](int every) {
    firmware::TrackingOptions options;
    options.mapping_thread = false;
    options.use_gyro = false;
    options.global_adjustment_keyframes = every;
    firmware::TrackingAndMapping system(synthetic_rig(cam), options);
    for (const StereoFrame& f : frames) {
      EXPECT_EQ(system.on_stereo(f).state, dsp::TrackingState::kTracking);
    }
    (void)system.finish();
    return system.counters();
  };
  const firmware::TrackingCounters off = run(0);
  EXPECT_EQ(off.global_adjustments, 1u);
  EXPECT_EQ(off.corrections_applied, off.keyframes);
  const firmware::TrackingCounters every_third = run(3);
  ASSERT_GE(every_third.keyframes, 3u);
  EXPECT_EQ(every_third.keyframes, off.keyframes);
  EXPECT_EQ(every_third.global_adjustments, every_third.keyframes / 3 + 1);
  EXPECT_EQ(every_third.corrections_applied, every_third.keyframes + every_third.keyframes / 3);
}

// --- The real EuRoC still sequence ---------------------------------------------------------------

const recording::EurocRecording& euroc_still() {
  static const recording::EurocRecording rec =
      recording::read_euroc(std::filesystem::path(WALLAR_TEST_DATA) / "euroc_v1_01_still");
  return rec;
}

StereoFrame euroc_pair(std::size_t i) {
  const recording::EurocRecording& rec = euroc_still();
  StereoFrame f;
  f.t_ns = rec.cams[0].frames[i].t_ns;
  f.sequence = i;
  f.left.image = recording::load_image_gray(rec.cams[0].image_path(rec.cams[0].frames[i]));
  f.right.image = recording::load_image_gray(rec.cams[1].image_path(rec.cams[1].frames[i]));
  return f;
}

// Through the appliance's modules, as `wallar track` runs them: lock step and every frame with
// the mapping thread.
TEST(TrackerEuroc, StillSequenceDriftsLittleAndItsMapHoldsTheFloor) {
  for (const bool thread : {false, true}) {
    const firmware::ApplianceOptions options = firmware::offline_options(
        thread ? firmware::ApplianceMode::kEveryFrame : firmware::ApplianceMode::kLockStep);
    const std::atomic<bool> stop{false};
    const firmware::ApplianceReport report =
        firmware::run_over_recording(euroc_still(), firmware::BoardConfig{}, options, stop);
    firmware::RunEvaluationOptions eval_options;
    eval_options.gravity_aligned = true;
    eval_options.ground_truth = true;
    const firmware::RunEvaluation r = firmware::evaluate_run(euroc_still(), report, eval_options);
    SCOPED_TRACE(thread ? "mapping thread" : "lock step");
    ASSERT_EQ(report.trajectory.size(), 40u);
    EXPECT_EQ(report.frames_overwritten, 0u);
    for (const firmware::PoseRecord& f : report.trajectory) {
      EXPECT_EQ(f.state, dsp::TrackingState::kTracking);
      EXPECT_GT(f.times.total_ns, 0);  // the tracker's stage clock runs in the appliance
    }
    ASSERT_TRUE(r.drift_m && r.drift_deg);
    std::printf("EuRoC still (%s): drift %.4f m %.3f deg\n", thread ? "thread" : "lockstep",
                *r.drift_m, *r.drift_deg);
    EXPECT_LT(*r.drift_m, 0.01);
    EXPECT_LT(*r.drift_deg, 0.5);
    ASSERT_TRUE(r.floor.has_value());
    ASSERT_TRUE(r.floor->free_fit_vs_ground_truth_deg.has_value());
    std::printf("  floor: %zu points, free fit %.2f deg from ground-truth gravity\n",
                r.floor->inliers, *r.floor->free_fit_vs_ground_truth_deg);
    EXPECT_GT(r.floor->inliers, 50u);
    EXPECT_LT(*r.floor->free_fit_vs_ground_truth_deg, 2.0);
    EXPECT_NEAR(r.floor->distance_below_m, 0.93, 0.1);  // the IMU sits ~0.93 m above the floor
    // The map is in the gravity-aligned body world: the floor points are below, not beside.
    EXPECT_GT(r.outputs.map.size(), 150u);
  }
}

// A tracker that keeps up with only every sixth frame (an emulator, a loaded board) integrates
// the gyro over 0.3 s between its frames, residual bias and all. The gyro's trust shrinks with
// that interval (gyro_prior_sigma_deg), so the map holds the pose of a still camera; a sigma
// fixed per frame, whatever the interval, lets the pose follow the bias.
TEST(TrackerEuroc, EverySixthFrameWithABiasedGyroStaysPut) {
  const recording::EurocRecording& rec = euroc_still();
  const auto drift_after = [&](double sigma_interval_s) {
    firmware::TrackingOptions options;
    options.mapping_thread = false;
    options.tracker.gyro_rotation_sigma_deg = 0.01;  // tight, so a bias shows
    options.tracker.gyro_sigma_interval_s = sigma_interval_s;
    firmware::TrackingAndMapping system(rec.rig(), options);
    // The rig stands still: its mean rate is the gyro's bias. The attitude filter's estimate
    // (the prior holds the pose only with one) misses it by 0.43 deg/s.
    Eigen::Vector3d mean_rad_s = Eigen::Vector3d::Zero();
    for (const ImuSample& s : rec.imu) mean_rad_s += s.gyro_rad_s;
    mean_rad_s /= static_cast<double>(rec.imu.size());
    system.set_gyro_bias(mean_rad_s - Eigen::Vector3d(0.004, -0.006, 0.002));
    std::size_t next_imu = 0;
    double max_m = 0.0, max_deg = 0.0;
    for (std::size_t i = 0; i < rec.cams[0].frames.size(); i += 6) {
      const StereoFrame frame = euroc_pair(i);
      for (; next_imu < rec.imu.size() && rec.imu[next_imu].t_ns <= frame.t_ns; ++next_imu) {
        system.on_imu(rec.imu[next_imu]);
      }
      const dsp::TrackResult r = system.on_stereo(frame);
      EXPECT_EQ(r.state, dsp::TrackingState::kTracking) << "frame " << i;
      max_m = std::max(max_m, r.T_world_cam.translation().norm());
      max_deg = std::max(max_deg, Eigen::AngleAxisd(r.T_world_cam.rotation()).angle() * 180 / M_PI);
    }
    return std::pair{max_m, max_deg};
  };
  const auto [shrinking_m, shrinking_deg] = drift_after(dsp::TrackerConfig{}.gyro_sigma_interval_s);
  const auto [fixed_m, fixed_deg] = drift_after(1.0);  // 0.3 s trusted like one 20 Hz frame
  std::printf("every 6th frame, biased gyro: %.2f mm %.3f deg (fixed sigma: %.2f mm %.3f deg)\n",
              shrinking_m * 1e3, shrinking_deg, fixed_m * 1e3, fixed_deg);
  EXPECT_LT(shrinking_m, 0.005);  // measured 1.9 mm, 0.09 deg; without the gyro 0.2 mm, 0.06 deg
  EXPECT_LT(shrinking_deg, 0.15);
  EXPECT_GT(fixed_m, 2 * shrinking_m);  // the check above would catch the fixed sigma
}

TEST(TrackerEuroc, OnePairMakesAMap) {
  firmware::TrackingOptions options;
  options.mapping_thread = false;
  firmware::TrackingAndMapping system(euroc_still().rig(), options);
  const dsp::TrackResult r = system.on_stereo(euroc_pair(0));
  EXPECT_EQ(r.state, dsp::TrackingState::kTracking);
  EXPECT_TRUE(r.keyframe);
  const auto map = system.finish();
  ASSERT_TRUE(map != nullptr);
  EXPECT_GT(map->points.size(), 150u);
  EXPECT_EQ(map->keyframe_centres.size(), 1u);
  ASSERT_EQ(map->viewer_offset.size(), map->points.size() + 1);
  EXPECT_EQ(map->viewer_index.size(), map->points.size());  // one pair: one viewer each
}

// What a frame tracked, for embedders (the VIT features): one entry per inlier track, each
// at its map point's projection (within the pose's inlier radius) and that point's depth; the
// same points again in the next frame; nothing once lost or before the first frame.
TEST(TrackerEuroc, FrameFeaturesAreTheInlierTracksAtTheirPointsDepths) {
  firmware::TrackingOptions options;
  options.mapping_thread = false;
  firmware::TrackingAndMapping system(euroc_still().rig(), options);
  const dsp::Tracker& tracker = system.tracker();
  std::vector<dsp::FrameFeature> features(static_cast<std::size_t>(tracker.config().max_tracks));
  EXPECT_EQ(tracker.frame_features(features), 0u);  // nothing tracked yet
  std::vector<dsp::PointRef> first;
  for (std::size_t i = 0; i < 3; ++i) {
    const dsp::TrackResult r = system.on_stereo(euroc_pair(i));
    ASSERT_EQ(r.state, dsp::TrackingState::kTracking);
    const std::size_t n = tracker.frame_features(features);
    SCOPED_TRACE("frame " + std::to_string(i));
    // The first frame's are its key-frame's new points; later ones the pose's inliers.
    EXPECT_EQ(n, static_cast<std::size_t>(i == 0 ? r.new_points : r.inliers));
    ASSERT_GT(n, 100u);
    const SE3d T_cam_world = r.T_world_cam.inverse();
    std::size_t kept = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const dsp::FrameFeature& f = features[k];
      const dsp::MapPoint& p = tracker.map_points()[static_cast<std::size_t>(f.point.id)];
      ASSERT_TRUE(p.alive);
      EXPECT_EQ(p.generation, f.point.generation);
      const Eigen::Vector3d p_cam = T_cam_world * p.p_world;
      EXPECT_NEAR(f.depth_m, p_cam.z(), 1e-4 * p_cam.z());
      const Eigen::Vector3d uvr = tracker.intrinsics().project(p_cam);
      EXPECT_LT(std::hypot(uvr.x() - f.u_px, uvr.y() - f.v_px), 2.5);
      if (std::isfinite(f.u_right_px)) {
        EXPECT_LT(std::abs(uvr.z() - f.u_right_px), 2.5);
      }
      if (i == 0) first.push_back(f.point);
      kept += std::find(first.begin(), first.end(), f.point) != first.end() ? 1 : 0;
    }
    EXPECT_GT(kept, n * 9 / 10);  // a still camera tracks the first frame's points on
  }
}

// EuRoC's cameras are distorted: the right image is rectified only where the stereo searches
// read it. Every pose, track and map point must come out as with the whole image rectified.
TEST(TrackerEuroc, TheRightImageRectifiedOnDemandTracksAsTheWholeImageDoes) {
  const auto run = [](bool on_demand) {
    firmware::TrackingOptions options;
    options.mapping_thread = false;
    options.tracker.right_on_demand = on_demand;
    firmware::TrackingAndMapping system(euroc_still().rig(), options);
    std::vector<dsp::TrackResult> results;
    for (std::size_t i = 0; i < euroc_still().cams[0].frames.size(); ++i) {
      results.push_back(system.on_stereo(euroc_pair(i)));
    }
    std::vector<dsp::MapPoint> points(system.tracker().map_points().begin(),
                                      system.tracker().map_points().end());
    return std::pair{results, points};
  };
  const auto [lazy, lazy_points] = run(true);
  const auto [whole, whole_points] = run(false);
  ASSERT_EQ(lazy.size(), whole.size());
  ASSERT_GE(lazy.size(), 40u);
  for (std::size_t i = 0; i < lazy.size(); ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    EXPECT_EQ(lazy[i].state, dsp::TrackingState::kTracking);
    EXPECT_EQ(lazy[i].tracked, whole[i].tracked);
    EXPECT_EQ(lazy[i].inliers, whole[i].inliers);
    EXPECT_EQ(lazy[i].new_points, whole[i].new_points);
    EXPECT_TRUE(lazy[i].T_world_cam.matrix() == whole[i].T_world_cam.matrix());
  }
  ASSERT_EQ(lazy_points.size(), whole_points.size());
  int stereo = 0;
  for (std::size_t k = 0; k < lazy_points.size(); ++k) {
    EXPECT_EQ(lazy_points[k].alive, whole_points[k].alive);
    EXPECT_TRUE(lazy_points[k].p_world == whole_points[k].p_world) << "point " << k;
    stereo += lazy_points[k].alive ? 1 : 0;
  }
  EXPECT_GT(stereo, 150);  // the key-frame's points: each one's depth from a row search
}

// A reset on the tracking thread (SCHED_FIFO on a headset) never waits for the mapping thread,
// which may be inside a bundle adjustment for a while: here one held 1 s. The old map's
// key-frame is mapped meanwhile, and its correction is dropped, never applied to the new map;
// the same mapping thread then maps the new one.
TEST(TrackerEuroc, AResetNeverWaitsForTheMappingThreadAndDropsTheOldMapsCorrection) {
  firmware::TrackingOptions options;
  options.mapping_thread = true;
  options.use_gyro = false;
  std::atomic<int> mapped{0};
  std::atomic<bool> in_first{false};
  options.before_mapping = [&] {
    if (mapped.fetch_add(1) == 0) {
      in_first.store(true);
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  };
  firmware::TrackingAndMapping system(euroc_still().rig(), options);
  const firmware::RtThread* mapping = system.mapping_thread();
  ASSERT_NE(mapping, nullptr);
  ASSERT_TRUE(system.on_stereo(euroc_pair(0)).keyframe);
  while (!in_first.load()) std::this_thread::yield();
  const TimeNs t0 = monotonic_now_ns();
  system.reset();
  const DurationNs reset_ns = monotonic_now_ns() - t0;
  EXPECT_LT(reset_ns, 100 * kNsPerMs) << "the reset waited for the mapping thread";
  EXPECT_EQ(system.mapping_thread(), mapping);
  EXPECT_FALSE(mapping->finished());
  // The new map: its first key-frame, and frames until the old map's correction has come and
  // gone (the mapping thread's second key-frame is the new map's).
  ASSERT_TRUE(system.on_stereo(euroc_pair(1)).keyframe);
  for (std::size_t i = 2; i < 40 && mapped.load() < 2; ++i) {
    (void)system.on_stereo(euroc_pair(i % 10 + 1));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_GE(mapped.load(), 2);
  // Both key-frames were mapped; only the new map's correction was applied.
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  (void)system.on_stereo(euroc_pair(2));
  EXPECT_EQ(system.counters().corrections_applied, 1u);
  const auto map = system.finish();
  ASSERT_TRUE(map != nullptr);
  EXPECT_EQ(map->keyframe_centres.size(), 1u);  // the new map's key-frame alone
  EXPECT_GT(map->points.size(), 150u);
}

// --- Bad input: blank and dark frames, repeats and gaps, wrong sizes -----------------------------

TEST(TrackerBadInput, BlankStartDarkMiddleRepeatsAndGapsWrongSizes) {
  firmware::TrackingOptions options;
  options.mapping_thread = false;
  firmware::TrackingAndMapping system(euroc_still().rig(), options);
  const auto pose_ok = [](const dsp::TrackResult& r) {
    return r.T_world_cam.matrix().allFinite() && r.T_world_cam.translation().norm() < 0.01;
  };
  const StereoFrame first = euroc_pair(0);
  // A blank wall: nothing to start a map from; the tracker says so and waits.
  for (int i = 0; i < 3; ++i) {
    StereoFrame blank = first;
    blank.left.image = filled(752, 480, 128);
    blank.right.image = filled(752, 480, 128);
    const dsp::TrackResult r = system.on_stereo(blank);
    EXPECT_EQ(r.state, dsp::TrackingState::kInitialising);
    EXPECT_TRUE(pose_ok(r));
  }
  // Real frames, with a repeated frame and a gap.
  for (std::size_t i : {0, 1, 1, 1, 5, 9, 10, 10}) {
    const dsp::TrackResult r = system.on_stereo(euroc_pair(i));
    EXPECT_EQ(r.state, dsp::TrackingState::kTracking) << "frame " << i;
    EXPECT_TRUE(pose_ok(r)) << "frame " << i;
  }
  // The lights go out: lost, the pose held (never NaN).
  for (int i = 0; i < 3; ++i) {
    StereoFrame dark = euroc_pair(11);
    dark.left.image = filled(752, 480, 0);
    dark.right.image = filled(752, 480, 0);
    const dsp::TrackResult r = system.on_stereo(dark);
    EXPECT_EQ(r.state, dsp::TrackingState::kLost);
    EXPECT_TRUE(pose_ok(r));
  }
  // A frame of the wrong size is refused and changes nothing.
  StereoFrame small = euroc_pair(12);
  small.left.image = filled(640, 480, 100);
  small.right.image = filled(640, 480, 100);
  const dsp::TrackResult refused = system.on_stereo(small);
  ASSERT_NE(refused.rejected, nullptr);
  EXPECT_EQ(refused.state, dsp::TrackingState::kLost);
  // Light again: relocalised against the key-frame, back to tracking where it was.
  const dsp::TrackResult back = system.on_stereo(euroc_pair(13));
  EXPECT_EQ(back.state, dsp::TrackingState::kTracking);
  EXPECT_TRUE(back.relocalised);
  EXPECT_TRUE(pose_ok(back));
  for (std::size_t i = 14; i < 20; ++i) {
    EXPECT_EQ(system.on_stereo(euroc_pair(i)).state, dsp::TrackingState::kTracking);
  }
  const firmware::TrackingCounters c = system.counters();
  EXPECT_EQ(c.lost_frames, 3u);
  EXPECT_EQ(c.rejected_frames, 1u);
  EXPECT_EQ(c.relocalisations, 1u);
}

TEST(TrackerBadInput, ACalibrationThatDoesNotFitTheImagesIsAClearError) {
  recording::EurocRecording rec = euroc_still();
  for (auto& cam : rec.cams) {
    cam.calib.width_px = 640;  // the images are 752 wide
    cam.frames.resize(3);
  }
  const std::atomic<bool> stop{false};
  try {
    const firmware::ApplianceOptions options =
        firmware::offline_options(firmware::ApplianceMode::kEveryFrame);
    (void)firmware::run_over_recording(rec, firmware::BoardConfig{}, options, stop);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    // The replay checks each image against the calibration and names the file.
    EXPECT_NE(std::string(e.what()).find("image is 752x480, expected 640x480"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace wallar
