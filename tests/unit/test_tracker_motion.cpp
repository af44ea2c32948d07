// SPDX-License-Identifier: Apache-2.0
/// @file test_tracker_motion.cpp
/// @brief The tracker on a moving rig: map point identity across culls (a stale correction
/// never lands on an id's next point, also with the mapper on its own thread), exposure steps
/// (Lucas-Kanade, patch search), descriptors, relocalisation away from key-frame poses, new map
/// segments after a lasting loss, and the mapper's bounded map (redundant key-frames, points
/// nobody sees again).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "test_support.hpp"
#include "tracking_support.hpp"
#include "wallar/dsp/eval/trajectory.hpp"
#include "wallar/dsp/tracking/features.hpp"
#include "wallar/dsp/tracking/klt.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/tracking/synthetic_room.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/firmware/tracking_and_mapping.hpp"

namespace wallar {
namespace {

using dsp::SyntheticCamera;
using dsp::SyntheticRoom;

using test::short_tests;

using test::small_room;

using test::gray_view;
using test::stereo;

Image scaled(const Image& in, double gain, double bias) {
  Image out = Image::allocate(in.width(), in.height(), PixelFormat::kGray8);
  for (int y = 0; y < in.height(); ++y) {
    const std::uint8_t* a = in.data() + std::ptrdiff_t{y} * in.stride_bytes();
    std::uint8_t* b = out.mutable_data() + std::ptrdiff_t{y} * out.stride_bytes();
    for (int x = 0; x < in.width(); ++x) {
      b[x] = static_cast<std::uint8_t>(std::clamp(std::lround(gain * a[x] + bias), 0L, 255L));
    }
  }
  return out;
}

Image black(int w, int h) {
  Image img = Image::allocate(w, h, PixelFormat::kGray8);
  std::fill_n(img.mutable_data(), static_cast<std::size_t>(w * h), std::uint8_t{0});
  return img;
}

double angle_deg(const Eigen::Matrix3d& R) { return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI; }

// --- Exposure steps and appearance --------------------------------------------------------------

TEST(TrackerExposure, LucasKanadeFollowsAShiftThroughAGainStep) {
  const SyntheticRoom room = small_room();
  const SyntheticCamera cam;
  const SE3d T0 = dsp::synthetic_trajectory(room, 1, 10.0)[0].T_world_body;
  const Image left = dsp::render_room_image(room, cam, T0, 0);
  // The right image with the exposure up 60 % and the black level down (clipped at 0 and 255).
  const Image right = scaled(dsp::render_room_image(room, cam, T0, 1), 1.6, -30.0);
  dsp::Pyramid prev(cam.width_px, cam.height_px, 3), cur(cam.width_px, cam.height_px, 3);
  prev.build(gray_view(left));
  cur.build(gray_view(right));
  const dsp::FixedVector<dsp::Corner> corners = test::detect_corners(left, 300);
  // The brightness relation from samples at corresponding places (the true disparity here; the
  // tracker uses the predicted ones).
  std::vector<float> a, b;
  std::vector<double> disparity;
  for (const dsp::Corner& c : corners) {
    const Eigen::Vector3d ray((c.u_px - cam.cx_px) / cam.f_px, (c.v_px - cam.cy_px) / cam.f_px,
                              1.0);
    const auto hit = dsp::ray_hit(room, T0.translation(), T0.linear() * ray);
    const double d = cam.f_px * cam.baseline_m / hit->range;
    disparity.push_back(d);
    const dsp::GrayView P = prev.level(2), C = cur.level(2);
    const float px = (c.u_px + 0.5f) / 4 - 0.5f, py = (c.v_px + 0.5f) / 4 - 0.5f;
    const float cx = (c.u_px - static_cast<float>(d) + 0.5f) / 4 - 0.5f;
    if (P.inside(px, py, 1) && C.inside(cx, py, 1)) {
      a.push_back(P.sample(px, py));
      b.push_back(C.sample(cx, py));
    }
  }
  const dsp::Brightness brightness = dsp::estimate_brightness(a, b);
  // Roughly: the brightest pixels clip at 255 (the spreads shrink).
  EXPECT_GT(brightness.gain, 1.2);
  EXPECT_LT(brightness.gain, 1.9);
  const auto count_good = [&](const dsp::Brightness& model) {
    int good = 0;
    for (std::size_t i = 0; i < corners.size(); ++i) {
      const dsp::Corner& c = corners[i];
      float u = c.u_px, v = c.v_px;
      if (!dsp::klt_track(prev, cur, c.u_px, c.v_px, u, v, {}, model)) continue;
      good += std::abs((c.u_px - u) - disparity[i]) < 0.3 && std::abs(v - c.v_px) < 0.3 ? 1 : 0;
    }
    return good;
  };
  const int with = count_good(brightness), without = count_good({});
  // The same pair without the exposure change: what translation-only windows manage here.
  dsp::Pyramid same(cam.width_px, cam.height_px, 3);
  same.build(gray_view(dsp::render_room_image(room, cam, T0, 1)));
  std::swap(cur, same);
  const int unchanged = count_good({});
  std::printf(
      "gain step: %d of %zu corners tracked to 0.3 px with the brightness model, %d "
      "without; %d with no exposure change\n",
      with, corners.size(), without, unchanged);
  EXPECT_GT(with, unchanged * 8 / 10);
  EXPECT_LT(without, unchanged / 4);
}

TEST(TrackerExposure, PatchSearchIgnoresGainAndRefusesAFlatWindow) {
  const SyntheticRoom room = small_room();
  const SyntheticCamera cam;
  const SE3d T0 = dsp::synthetic_trajectory(room, 1, 10.0)[0].T_world_body;
  const Image img = dsp::render_room_image(room, cam, T0, 0);
  const Image brighter = scaled(img, 1.5, 10.0);
  const dsp::FixedVector<dsp::Corner> corners = test::detect_corners(img, 100);
  int found = 0, tried = 0;
  for (const dsp::Corner& c : corners) {
    dsp::Patch8 patch;
    if (!dsp::extract_patch(gray_view(img), c.u_px, c.v_px, patch)) continue;
    ++tried;
    float cost = 0.0f;
    const float u0 = std::round(c.u_px), v0 = std::round(c.v_px);
    const auto hit = dsp::search_patch(gray_view(brighter), patch, u0 + 3.0f, v0 - 2.0f, 8, &cost);
    found +=
        hit && std::abs(hit->first - u0) < 0.6f && std::abs(hit->second - v0) < 0.6f && cost < 8.0f
            ? 1
            : 0;
  }
  EXPECT_GT(found, tried * 8 / 10);
  // A frame gone dark: nothing there to match, whatever the patch.
  const Image dark = black(cam.width_px, cam.height_px);
  dsp::Patch8 patch;
  ASSERT_TRUE(dsp::extract_patch(gray_view(img), corners[0].u_px, corners[0].v_px, patch));
  EXPECT_FALSE(
      dsp::search_patch(gray_view(dark), patch, corners[0].u_px, corners[0].v_px, 8, nullptr));
}

TEST(TrackerExposure, DescriptorsOfOnePlaceAgreeAcrossViewsAndDifferElsewhere) {
  const SyntheticRoom room = small_room();
  const SyntheticCamera cam;
  const std::vector<StampedPose> path = dsp::synthetic_trajectory(room, 40, 10.0);
  const SE3d Ta = path[0].T_world_body, Tb = path[30].T_world_body;  // 3 s apart
  ASSERT_GT(angle_deg(Ta.linear().transpose() * Tb.linear()), 5.0);
  const Image ia = dsp::render_room_image(room, cam, Ta, 0),
              ib = dsp::render_room_image(room, cam, Tb, 0);
  dsp::Pyramid pa(cam.width_px, cam.height_px, 2), pb(cam.width_px, cam.height_px, 2);
  pa.build(gray_view(ia));
  pb.build(gray_view(ib));
  const dsp::FixedVector<dsp::Corner> corners = test::detect_corners(ia, 400);
  std::vector<int> same, other;
  std::vector<dsp::Descriptor256> in_b;
  for (const dsp::Corner& c : corners) {
    const Eigen::Vector3d ray((c.u_px - cam.cx_px) / cam.f_px, (c.v_px - cam.cy_px) / cam.f_px,
                              1.0);
    const auto hit = dsp::ray_hit(room, Ta.translation(), Ta.linear() * ray);
    const Eigen::Vector3d p_b = Tb.inverse() * hit->p_world;
    if (p_b.z() < 0.3) continue;
    const double ub = cam.f_px * p_b.x() / p_b.z() + cam.cx_px,
                 vb = cam.f_px * p_b.y() / p_b.z() + cam.cy_px;
    dsp::Descriptor256 da, db;
    if (!dsp::compute_descriptor(pa.level(1), c.u_px, c.v_px, da) ||
        !dsp::compute_descriptor(pb.level(1), static_cast<float>(ub), static_cast<float>(vb), db)) {
      continue;
    }
    same.push_back(dsp::hamming_distance(da, db));
    if (!in_b.empty()) other.push_back(dsp::hamming_distance(da, in_b.back()));
    in_b.push_back(db);
  }
  ASSERT_GT(same.size(), 50u);
  std::sort(same.begin(), same.end());
  std::sort(other.begin(), other.end());
  const int same_median = same[same.size() / 2], other_median = other[other.size() / 2];
  std::printf("descriptors: same place median %d bits, other places %d bits (of 256)\n",
              same_median, other_median);
  EXPECT_LT(same_median, 64);
  EXPECT_GT(other_median, 100);
}

// --- Map point identity --------------------------------------------------------------------------

/// A tracker and its mapper in lock step over the start of the rendered room's path.
struct LockStep {
  SyntheticRoom room = small_room();
  SyntheticCamera cam;
  std::vector<StampedPose> path;
  dsp::Tracker tracker;
  dsp::Mapper mapper;
  dsp::MapCorrection correction{20000, 256};
  std::size_t next = 0;

  explicit LockStep(const dsp::TrackerConfig& config = {})
      : path(dsp::synthetic_trajectory(room, 200, 10.0)),
        tracker(dsp::synthetic_rig(cam), config),
        mapper(tracker.intrinsics()) {}
  dsp::TrackResult step() {
    const StampedPose& p = path[next++];
    const StereoFrame f = stereo(room, cam, p.T_world_body, p.t_ns);
    const dsp::TrackResult r = tracker.track(p.t_ns, f.left.image, f.right.image);
    if (const dsp::KeyframeMessage* kf = tracker.pending_keyframe()) {
      mapper.add_keyframe(*kf);
      mapper.local_adjust(correction);
      tracker.apply(correction);
    }
    return r;
  }
};

TEST(TrackerIdentity, AStaleCorrectionOrCullNeverLandsOnTheIdsNextPoint) {
  LockStep s;
  for (int i = 0; i < 3; ++i) ASSERT_EQ(s.step().state, dsp::TrackingState::kTracking);
  // A live point, and a correction for it as a mapping thread would hold it.
  std::int32_t id = -1;
  for (std::size_t i = 0; i < s.tracker.map_points().size(); ++i) {
    if (s.tracker.map_points()[i].alive) id = static_cast<std::int32_t>(i);
  }
  ASSERT_GE(id, 0);
  const dsp::MapPoint old_point = s.tracker.map_points()[static_cast<std::size_t>(id)];
  dsp::MapCorrection stale(16, 4);
  stale.points.push_back(
      {id, old_point.generation, old_point.p_world + Eigen::Vector3d(0.5, 0.5, 0.5), 0.01f});
  // Meanwhile the point is culled (the mapper's own verdict) and its id freed ...
  dsp::MapCorrection cull(16, 4);
  cull.culled.push_back({id, old_point.generation});
  s.tracker.apply(cull);
  EXPECT_FALSE(s.tracker.map_points()[static_cast<std::size_t>(id)].alive);
  // ... and the next key-frame makes a new point in the same slot.
  for (int i = 0; i < 40 && !s.tracker.map_points()[static_cast<std::size_t>(id)].alive; ++i) {
    s.step();
  }
  const dsp::MapPoint reborn = s.tracker.map_points()[static_cast<std::size_t>(id)];
  ASSERT_TRUE(reborn.alive) << "no key-frame reused the freed id";
  EXPECT_EQ(reborn.generation, old_point.generation + 1);
  // The stale correction and a stale cull arrive now: neither touches the new point.
  s.tracker.apply(stale);
  dsp::MapCorrection stale_cull(16, 4);
  stale_cull.culled.push_back({id, old_point.generation});
  s.tracker.apply(stale_cull);
  const dsp::MapPoint after = s.tracker.map_points()[static_cast<std::size_t>(id)];
  EXPECT_TRUE(after.alive);
  EXPECT_EQ(after.p_world, reborn.p_world);
  EXPECT_EQ(s.step().stale_updates, 2);
  // The mapper ignores a cull of the old generation too (it holds the new point).
  dsp::KeyframeMessage msg(8, 8);
  msg.id = 10000;
  msg.T_world_cam = SE3d::Identity();
  msg.culled.push_back({id, old_point.generation});
  const std::uint64_t stale_before = s.mapper.stale_messages();
  const dsp::MapSnapshot before = s.mapper.snapshot();
  s.mapper.add_keyframe(msg);
  EXPECT_EQ(s.mapper.stale_messages(), stale_before + 1);
  const dsp::MapSnapshot now = s.mapper.snapshot();
  EXPECT_NE(std::find(now.point_ids.begin(), now.point_ids.end(), id), now.point_ids.end());
  EXPECT_EQ(now.points.size(), before.points.size());
}

TEST(TrackerIdentity, MappingOnItsThreadWhileIdsAreReusedKeepsThePointsOnTheRoom) {
  // A small map that culls eagerly: ids come back while the mapping thread still adjusts their
  // previous points. Whatever the interleaving, no point may end up off the room's surfaces
  // (a correction for an id's previous point would put it where that point was).
  const SyntheticRoom room = small_room();
  const SyntheticCamera cam;
  firmware::TrackingOptions options;
  options.tracker.max_map_points = 900;
  options.tracker.keyframe_points = 300;
  options.tracker.cull_after_visible = 4;
  options.tracker.cull_found_ratio = 0.6;
  options.tracker.keyframe_distance_ratio = 0.05;
  options.mapping_thread = true;
  firmware::TrackingAndMapping system(dsp::synthetic_rig(cam), options);
  const std::vector<StampedPose> path =
      dsp::synthetic_trajectory(room, short_tests() ? 40 : 100, 5.0);
  int tracked = 0;
  for (const StampedPose& p : path) {
    tracked += system.on_stereo(stereo(room, cam, p.T_world_body, p.t_ns)).state ==
                       dsp::TrackingState::kTracking
                   ? 1
                   : 0;
  }
  const auto map = system.finish();
  const firmware::TrackingCounters c = system.counters();
  std::printf(
      "ids reused under a mapping thread: %llu key-frames, %llu culled, %llu stale "
      "updates ignored, %d of %zu frames tracked\n",
      static_cast<unsigned long long>(c.keyframes),
      static_cast<unsigned long long>(c.culled_points),
      static_cast<unsigned long long>(c.stale_updates), tracked, path.size());
  EXPECT_EQ(tracked, static_cast<int>(path.size()));
  ASSERT_TRUE(map != nullptr);
  const SE3d T_world0 = path.front().T_world_body;
  std::vector<double> distance;
  for (const dsp::MapPoint& p : system.tracker().map_points()) {
    if (p.alive) distance.push_back(room.distance_to_nearest_surface(T_world0 * p.p_world));
  }
  ASSERT_GT(distance.size(), 200u);
  std::sort(distance.begin(), distance.end());
  EXPECT_LT(distance[distance.size() / 2], 0.01);
  EXPECT_LT(distance[distance.size() * 95 / 100], 0.10);
}

// --- Relocalisation and segments -----------------------------------------------------------------

TEST(TrackerRelocalisation, ByAppearanceAwayFromEveryKeyframePose) {
  dsp::TrackerConfig config;
  LockStep s(config);
  for (int i = 0; i < 30; ++i) ASSERT_EQ(s.step().state, dsp::TrackingState::kTracking);
  // The lights go out: lost.
  const Image dark = black(s.cam.width_px, s.cam.height_px);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(s.tracker.track(s.path[30].t_ns + i, dark, dark).state, dsp::TrackingState::kLost);
  }
  // Back on at a pose no key-frame had: 25 cm aside, turned 25 deg (beyond what a search by
  // patches around the key-frames' poses reaches).
  const SE3d T_world0 = s.path.front().T_world_body;
  SE3d T = s.path[15].T_world_body;
  T.translation() += T.linear() * Eigen::Vector3d(0.25, 0.05, 0.0);
  T.linear() = T.linear() *
               Eigen::AngleAxisd(25.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const StereoFrame f = stereo(s.room, s.cam, T, s.path[31].t_ns);
  const dsp::TrackResult r = s.tracker.track(f.t_ns, f.left.image, f.right.image);
  ASSERT_EQ(r.state, dsp::TrackingState::kTracking);
  EXPECT_TRUE(r.relocalised);
  const SE3d truth = T_world0.inverse() * T;  // in the tracker's world (its first camera)
  EXPECT_LT((r.T_world_cam.translation() - truth.translation()).norm(), 0.02);
  EXPECT_LT(angle_deg(r.T_world_cam.linear().transpose() * truth.linear()), 0.5);
  // Acceptance: a view of a room the map never saw is not taken for a place in it.
  const SyntheticRoom elsewhere = small_room(99);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(s.tracker.track(s.path[32].t_ns + i, dark, dark).state, dsp::TrackingState::kLost);
  }
  const StereoFrame g = stereo(elsewhere, s.cam, s.path[20].T_world_body, s.path[33].t_ns);
  EXPECT_FALSE(s.tracker.track(g.t_ns, g.left.image, g.right.image).relocalised);
}

TEST(TrackerSegments, ALastingLossStartsANewSegmentWhereTheMotionCarriedThePose) {
  dsp::TrackerConfig config;
  LockStep s(config);
  const SE3d T_world0 = s.path.front().T_world_body;
  for (int i = 0; i < 20; ++i) ASSERT_EQ(s.step().state, dsp::TrackingState::kTracking);
  // The room changes its look (another texture, same walls): nothing to track or relocalise
  // against. After new_segment_after_lost frames a new map starts there.
  const SyntheticRoom other = small_room(7);
  int lost = 0, segments = 0;
  dsp::TrackResult r;
  std::size_t k = 20;
  for (; k < 40; ++k) {
    const StereoFrame f = stereo(other, s.cam, s.path[k].T_world_body, s.path[k].t_ns);
    r = s.tracker.track(f.t_ns, f.left.image, f.right.image);
    lost += r.state == dsp::TrackingState::kLost ? 1 : 0;
    if (r.new_segment) {
      ++segments;
      // The new segment starts where the motion model carried the pose: continuous output.
      const SE3d truth = T_world0.inverse() * s.path[k].T_world_body;
      EXPECT_LT((r.T_world_cam.translation() - truth.translation()).norm(), 0.05);
      EXPECT_LT(angle_deg(r.T_world_cam.linear().transpose() * truth.linear()), 3.0);
      break;
    }
  }
  EXPECT_EQ(segments, 1);
  // The new_segment_after_lost-th frame in a row that fails starts the segment.
  EXPECT_EQ(lost, config.new_segment_after_lost - 1);
  EXPECT_EQ(r.segment, 1);
  // It tracks on in the new segment, its motion the room's.
  const SE3d start_est = r.T_world_cam, start_truth = s.path[k].T_world_body;
  for (std::size_t j = k + 1; j < k + 20; ++j) {
    const StereoFrame f = stereo(other, s.cam, s.path[j].T_world_body, s.path[j].t_ns);
    r = s.tracker.track(f.t_ns, f.left.image, f.right.image);
    ASSERT_EQ(r.state, dsp::TrackingState::kTracking) << "frame " << j;
  }
  const SE3d moved_est = start_est.inverse() * r.T_world_cam;
  const SE3d moved_truth = start_truth.inverse() * s.path[k + 19].T_world_body;
  EXPECT_LT((moved_est.translation() - moved_truth.translation()).norm(), 0.01);
}

// --- The mapper's bounded map ----------------------------------------------------------------

/// Key-frame messages of a camera at `T_world_cam` seeing `points` (exact stereo projections).
dsp::KeyframeMessage message_at(std::int32_t id, const SE3d& T_world_cam,
                                const std::vector<Eigen::Vector3d>& points, std::int32_t first,
                                std::int32_t count, bool new_points,
                                const dsp::StereoIntrinsics& K) {
  dsp::KeyframeMessage m(points.size(), points.size());
  m.id = id;
  m.t_ns = id;
  m.T_world_cam = T_world_cam;
  m.segment_start = id == 0;
  const SE3d T_cw = T_world_cam.inverse();
  for (std::int32_t i = first; i < first + count; ++i) {
    const Eigen::Vector3d uvr = K.project(T_cw * points[static_cast<std::size_t>(i)]);
    m.observations.push_back({i, 1, static_cast<float>(uvr.x()), static_cast<float>(uvr.y()),
                              static_cast<float>(uvr.z())});
    if (new_points) m.new_points.push_back({i, 1, points[static_cast<std::size_t>(i)], 0.01f});
  }
  return m;
}

TEST(MapperBounds, AHeadStayingPutMakesRedundantKeyframesThatAreDropped) {
  const dsp::StereoIntrinsics K{450.0, 376.0, 240.0, 0.11};
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 300; ++i) {
    pts.emplace_back(-1.5 + 3.0 * (i % 20) / 19.0, -1.0 + 2.0 * (i / 20) / 14.0,
                     3.0 + 0.5 * (i % 3));
  }
  dsp::Mapper mapper(K);
  dsp::MapCorrection out(1000, 256);
  int max_adjusted = 0;
  for (int k = 0; k < 60; ++k) {
    SE3d T = SE3d::Identity();
    T.translation() = Eigen::Vector3d(0.01 * std::sin(k), 0.005 * std::cos(k), 0.0);  // a sway
    mapper.add_keyframe(message_at(k, T, pts, 0, 300, k == 0, K));
    const dsp::MapperStats s = mapper.local_adjust(out);
    max_adjusted = std::max(max_adjusted, s.adjusted_keyframes);
  }
  std::printf("60 key-frames of one view: %d kept, %llu dropped as redundant\n",
              mapper.keyframe_count(), static_cast<unsigned long long>(mapper.culled_keyframes()));
  EXPECT_LE(mapper.keyframe_count(), 12);
  EXPECT_GE(mapper.culled_keyframes(), 48u);
  EXPECT_EQ(mapper.points_count(), 300);  // the points stay (others see them)
  EXPECT_LE(max_adjusted, dsp::MapperConfig{}.local_keyframes);
}

TEST(MapperBounds, PointsNoLaterKeyframeSeesAreDropped) {
  const dsp::StereoIntrinsics K{450.0, 376.0, 240.0, 0.11};
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 200; ++i) {
    pts.emplace_back(-1.5 + 3.0 * (i % 20) / 19.0, -1.0 + 2.0 * (i / 20) / 9.0, 3.0);
  }
  dsp::Mapper mapper(K);
  dsp::MapCorrection out(1000, 256);
  // Key-frame 0 makes 200 points; the next ones see only the first 100 of them.
  mapper.add_keyframe(message_at(0, SE3d::Identity(), pts, 0, 200, true, K));
  std::size_t culled = 0;
  for (int k = 1; k <= dsp::MapperConfig{}.confirm_keyframes; ++k) {
    SE3d T = SE3d::Identity();
    T.translation().x() = 0.2 * k;
    mapper.add_keyframe(message_at(k, T, pts, 0, 100, false, K));
    mapper.local_adjust(out);
    culled += out.culled.size();
    for (const dsp::PointRef& r : out.culled) EXPECT_GE(r.id, 100);
  }
  EXPECT_EQ(culled, 100u);
  EXPECT_EQ(mapper.points_count(), 100);
}

TEST(MapperPriors, AGyroTrackedKeyframeIsTurnedLessByBiasedObservationsThanAVisionOnlyOne) {
  // A head turning on the spot: key-frame 0 looks at a wall, key-frame 1 is 30 deg further
  // round and shares half of its points. Key-frame 1 was made during the turn: its
  // observations are blurred (4 px) and sit 3 px off to one side, as a smear can. A local
  // adjustment explains that offset partly by moving the points and partly by turning key-frame
  // 1 (0.06 deg, vision only). Tracked with the gyro, its rotation is known better than that
  // and the adjustment must hold it.
  const dsp::StereoIntrinsics K{450.0, 376.0, 240.0, 0.11};
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 150; ++i) {
    const double a = (-20.0 + 50.0 * (i % 30) / 29.0) * M_PI / 180.0;  // -20..30 deg round
    const double y = -1.0 + 2.0 * (i / 30) / 4.0;
    pts.emplace_back(3.0 * std::sin(a), y, 3.0 * std::cos(a));
  }
  SE3d T1 = SE3d::Identity();
  T1.linear() = Eigen::AngleAxisd(30.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()).matrix();
  std::vector<int> in_view0;  // within 18 deg of key-frame 0's axis
  for (int i = 0; i < 150; ++i) {
    const Eigen::Vector3d& p = pts[static_cast<std::size_t>(i)];
    if (std::abs(std::atan2(p.x(), p.z())) < 18.0 * M_PI / 180.0) in_view0.push_back(i);
  }
  const auto turn_deg = [&](bool gyro) {
    dsp::Mapper mapper(K);
    dsp::MapCorrection out(1000, 256);
    dsp::KeyframeMessage m0(pts.size(), pts.size());
    m0.id = 0;
    m0.segment_start = true;
    m0.gyro_aided = gyro;
    for (int i : in_view0) {
      const Eigen::Vector3d uvr = K.project(pts[static_cast<std::size_t>(i)]);
      m0.observations.push_back({i, 1, static_cast<float>(uvr.x()), static_cast<float>(uvr.y()),
                                 static_cast<float>(uvr.z())});
      m0.new_points.push_back({i, 1, pts[static_cast<std::size_t>(i)], 0.01f});
    }
    mapper.add_keyframe(m0);
    mapper.local_adjust(out);
    dsp::KeyframeMessage m1(pts.size(), pts.size());
    m1.id = 1;
    m1.t_ns = 1;
    m1.T_world_cam = T1;
    m1.gyro_aided = gyro;
    m1.observation_sigma_px = 4.0f;
    const SE3d T1_cw = T1.inverse();
    for (int i = 0; i < 150; ++i) {
      const Eigen::Vector3d p_cam = T1_cw * pts[static_cast<std::size_t>(i)];
      const Eigen::Vector3d uvr = K.project(p_cam);
      if (p_cam.z() <= 0.0 || uvr.x() < 0.0 || uvr.x() >= 2.0 * K.cx_px) continue;
      const bool known = std::find(in_view0.begin(), in_view0.end(), i) != in_view0.end();
      m1.observations.push_back({i, 1, static_cast<float>(uvr.x() + 3.0),
                                 static_cast<float>(uvr.y()), static_cast<float>(uvr.z() + 3.0)});
      if (!known) m1.new_points.push_back({i, 1, pts[static_cast<std::size_t>(i)], 0.01f});
    }
    mapper.add_keyframe(m1);
    mapper.local_adjust(out);
    for (const dsp::MapCorrection::Keyframe& k : out.keyframes) {
      if (k.id != 1) continue;
      return Eigen::AngleAxisd(T1.linear().transpose() * k.T_world_cam.linear()).angle() * 180.0 /
             M_PI;
    }
    return 0.0;
  };
  const double vision_deg = turn_deg(false), gyro_deg = turn_deg(true);
  std::printf("key-frame 1 turned by the adjustment: %.3f deg vision only, %.3f deg gyro-aided\n",
              vision_deg, gyro_deg);
  EXPECT_GT(vision_deg, 0.04);  // the adjustment does see the offset
  EXPECT_LT(gyro_deg, 0.25 * vision_deg);
}

TEST(MapperBounds, TenMinutesOfNewKeyframesInOneRoomKeepTheMapAndTheAdjustmentTimeFlat) {
  // A key-frame every 0.5 s for ten minutes (1,200) from a head wandering a 6 x 5 x 2.7 m room
  // whose walls, floor and ceiling carry 3,000 points: every key-frame is new (a pose no other
  // had), unlike laps of one rendered loop, so the local adjustment runs each time. The
  // observations are the stereo projections with 0.3 px of seeded noise; points the mapper culls
  // come back as new ones (a new generation) when seen again, as the tracker would make them.
  const dsp::StereoIntrinsics K{450.0, 376.0, 240.0, 0.11};
  const int kKeyframes = test::short_tests() ? 120 : 1200;
  test::Rng rng(12345);
  std::vector<Eigen::Vector3d> world;
  while (world.size() < 3000) {
    const double a = rng.uniform(), b = rng.uniform();
    switch (world.size() % 6) {
      case 0:
        world.emplace_back(6.0 * a, 0.0, 2.7 * b);
        break;
      case 1:
        world.emplace_back(6.0 * a, 5.0, 2.7 * b);
        break;
      case 2:
        world.emplace_back(0.0, 5.0 * a, 2.7 * b);
        break;
      case 3:
        world.emplace_back(6.0, 5.0 * a, 2.7 * b);
        break;
      case 4:
        world.emplace_back(6.0 * a, 5.0 * b, 0.0);
        break;
      default:
        world.emplace_back(6.0 * a, 5.0 * b, 2.7);
        break;
    }
  }
  std::vector<std::uint32_t> generation(world.size(), 1);
  std::vector<bool> in_map(world.size(), false);
  dsp::Mapper mapper(K);
  dsp::MapCorrection out(4000, 4000);
  std::vector<double> ba_ms;
  int max_keyframes = 0, max_points = 0;
  std::size_t culled_points = 0;
  for (int k = 0; k < kKeyframes; ++k) {
    // A wander: the head drifts around the room's middle at walking pace and looks about.
    const double t = 0.5 * k;
    const Eigen::Vector3d c(3.0 + 1.8 * std::sin(0.11 * t) + 0.4 * std::sin(0.53 * t),
                            2.5 + 1.4 * std::cos(0.07 * t) + 0.3 * std::sin(0.41 * t),
                            1.6 + 0.1 * std::sin(0.9 * t));
    const double yaw = 0.9 * t + 0.6 * std::sin(0.37 * t), pitch = 0.25 * std::sin(0.23 * t);
    SE3d T_wc = SE3d::Identity();
    T_wc.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()))
                        .toRotationMatrix() *
                    (Eigen::Matrix3d() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished();
    T_wc.translation() = c;
    const SE3d T_cw = T_wc.inverse();
    dsp::KeyframeMessage m(world.size(), world.size());
    m.id = k;
    m.t_ns = static_cast<TimeNs>(t * 1e9);
    m.T_world_cam = T_wc;
    m.segment_start = k == 0;
    for (std::size_t i = 0; i < world.size(); ++i) {
      const Eigen::Vector3d p = T_cw * world[i];
      if (p.z() < 0.3 || p.z() > 8.0) continue;
      const Eigen::Vector3d uvr = K.project(p);
      if (uvr.x() < 0.0 || uvr.x() > 751.0 || uvr.y() < 0.0 || uvr.y() > 479.0) continue;
      const auto id = static_cast<std::int32_t>(i);
      const double nu = 0.3 * rng.gaussian(), nv = 0.3 * rng.gaussian(), nr = 0.3 * rng.gaussian();
      m.observations.push_back({id, generation[i], static_cast<float>(uvr.x() + nu),
                                static_cast<float>(uvr.y() + nv),
                                static_cast<float>(uvr.z() + nr)});
      if (!in_map[i]) {
        const double sigma = p.z() * p.z() / (K.f_px * K.baseline_m) * 0.5;
        m.new_points.push_back({id, generation[i], world[i], static_cast<float>(sigma)});
        in_map[i] = true;
      }
    }
    const auto t0 = std::chrono::steady_clock::now();
    mapper.add_keyframe(m);
    const dsp::MapperStats s = mapper.local_adjust(out);
    ba_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    for (const dsp::PointRef& r : out.culled) {
      if (r.id < 0 || r.generation != generation[static_cast<std::size_t>(r.id)]) continue;
      in_map[static_cast<std::size_t>(r.id)] = false;
      ++generation[static_cast<std::size_t>(r.id)];
      ++culled_points;
    }
    max_keyframes = std::max(max_keyframes, s.keyframes);
    max_points = std::max(max_points, s.points);
  }
  // Medians of the adjustment time per key-frame, minute by minute (120 key-frames a minute).
  const auto minute_median = [&](int minute) {
    std::vector<double> v(ba_ms.begin() + minute * 120, ba_ms.begin() + (minute + 1) * 120);
    std::nth_element(v.begin(), v.begin() + 60, v.end());
    return v[60];
  };
  const int minutes = kKeyframes / 120;
  std::printf(
      "%d key-frames over %d min: %d in the map at the end (at most %d), %llu dropped as "
      "redundant; points %d at the end (at most %d), %zu culled\n",
      kKeyframes, minutes, mapper.keyframe_count(), max_keyframes,
      static_cast<unsigned long long>(mapper.culled_keyframes()), mapper.points_count(), max_points,
      culled_points);
  for (int i = 0; i < minutes; ++i)
    std::printf("  minute %d: median add + local BA %.2f ms\n", i + 1, minute_median(i));
  // The room is covered in the first minutes: key-frames past that are redundant and dropped,
  // the points are the room's, and each adjustment costs what it did once the room was seen.
  EXPECT_LE(max_points, static_cast<int>(world.size()));
  EXPECT_LE(max_keyframes, 100);
  EXPECT_GE(mapper.culled_keyframes(), static_cast<std::uint64_t>(kKeyframes / 2));
  if (!test::short_tests()) {
    EXPECT_LE(minute_median(minutes - 1), 2.0 * minute_median(1));
  }
}

// --- What the wall search sees of a moving rig's map ------------------------------------------

// A map of key-frames along a path: cameras looking along +x, image-down = `down`.
dsp::MapSnapshot path_map(const std::vector<Eigen::Vector3d>& centres,
                          const Eigen::Vector3d& down) {
  dsp::MapSnapshot map;
  for (const Eigen::Vector3d& c : centres) {
    map.keyframe_centres.push_back(c);
    map.keyframe_image_down.push_back(down);
  }
  return map;
}

TEST(WallsOnTheMove, DownComesFromAPathOverTheGroundAndNotFromAHeadStandingStill) {
  const Eigen::Vector3d down(0.0, 0.0, -1.0);
  // A drive round a corner, 0.5 m up and down over bumps: flat against its 40 m extent.
  std::vector<Eigen::Vector3d> drive;
  for (int k = 0; k < 40; ++k) drive.emplace_back(k, 0.0, 0.02 * (k % 3));
  for (int k = 1; k < 30; ++k) drive.emplace_back(39.0, k, 0.02 * (k % 2));
  const auto from_drive = dsp::down_from_path(path_map(drive, down));
  ASSERT_TRUE(from_drive.has_value());
  EXPECT_GT(from_drive->dot(down), 0.999);
  // The cameras upside down: down is the other side of the same plane.
  const auto flipped = dsp::down_from_path(path_map(drive, -down));
  ASSERT_TRUE(flipped.has_value());
  EXPECT_LT(flipped->dot(down), -0.999);
  // A head standing in a room (centres within 30 cm), a path along one line, and a path climbing
  // as much as it goes: no down.
  std::vector<Eigen::Vector3d> standing, line, climb;
  for (int k = 0; k < 30; ++k) {
    standing.emplace_back(0.3 * std::cos(k), 0.3 * std::sin(k), 0.05 * std::sin(3 * k));
    line.emplace_back(k, 0.0, 0.0);
    climb.emplace_back(k % 6, k / 6, 0.8 * (k % 5));
  }
  EXPECT_FALSE(dsp::down_from_path(path_map(standing, down)).has_value());
  EXPECT_FALSE(dsp::down_from_path(path_map(line, down)).has_value());
  EXPECT_FALSE(dsp::down_from_path(path_map(climb, down)).has_value());
}

TEST(WallsOnTheMove, TheLocalMapIsWhatLiesAroundTheNewestKeyframe) {
  std::vector<Eigen::Vector3d> drive;
  for (int k = 0; k <= 100; k += 10) drive.emplace_back(k, 0.0, 0.0);  // newest at x = 100
  dsp::MapSnapshot map = path_map(drive, Eigen::Vector3d(0, 0, -1));
  for (int i = 0; i <= 100; ++i) {
    map.points.push_back(Eigen::Vector3f(static_cast<float>(i), 5.0f, 0.0f));
    map.points.observations.push_back(static_cast<std::uint16_t>(i + 1));
    map.sigma_m.push_back(i < 90 ? 1.0f : 0.05f * static_cast<float>(i - 89));  // 0.05 .. 0.55
  }
  dsp::LocalMap local;
  dsp::local_map(map, 12.0, local);
  // Points within 12 m of (100, 0, 0): x >= 90 (sqrt(10^2 + 5^2) < 12 < sqrt(11^2 + 5^2)).
  ASSERT_EQ(local.points.size(), 11u);
  EXPECT_FLOAT_EQ(local.points.point(0).x(), 90.0f);
  EXPECT_EQ(local.points.observations.front(), 91);
  EXPECT_EQ(local.viewpoints.size(), 2u);  // the key-frames at 90 and 100
  EXPECT_NEAR(local.median_sigma_m, 0.30, 1e-6);
  // Called again on a map of one point: nothing of the last call is left.
  dsp::MapSnapshot one = path_map({Eigen::Vector3d(0, 0, 0)}, Eigen::Vector3d(0, 0, -1));
  one.points.push_back(Eigen::Vector3f(1.0f, 0.0f, 0.0f));
  dsp::local_map(one, 12.0, local);
  EXPECT_EQ(local.points.size(), 1u);
  EXPECT_EQ(local.viewpoints.size(), 1u);
  EXPECT_EQ(local.median_sigma_m, 0.0);
}

}  // namespace
}  // namespace wallar
