// SPDX-License-Identifier: Apache-2.0
/// @file test_headset_view.cpp
/// @brief The firmware's headset view on the real EuRoC recording (floor overlay where the
/// floor is) and the walls.json round trip `wallar render --walls` relies on.
#include <gtest/gtest.h>

#include <chrono>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "test_support.hpp"
#include "wallar/drivers/display/display_output.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/firmware/headset_view.hpp"
#include "wallar/firmware/live_view.hpp"
#include "wallar/firmware/offline.hpp"
#include "wallar/firmware/report.hpp"

namespace wallar::test {
namespace {

TEST(WallsJson, RoundTripsTheWallsSchema) {
  dsp::RoomResult room;
  Wall w;
  w.id = 3;
  w.kind = SurfaceKind::kFloor;
  w.plane.n = Eigen::Vector3d(0.0, 0.0, 1.0);
  w.plane.d = -0.9;
  w.origin = Eigen::Vector3d(1.0, 2.0, -0.9);
  w.u = Eigen::Vector3d::UnitX();
  w.v = Eigen::Vector3d::UnitY();
  w.extent_uv_m = {{0.0, 0.0}, {2.0, 0.0}, {2.5, 1.5}, {0.0, 1.0}};
  room.surfaces.push_back({w, 1.0, 0.01, 10});
  const WallModel back = firmware::walls_from_json(firmware::to_json(room), "test");
  ASSERT_EQ(back.walls.size(), 1u);
  const Wall& b = back.walls[0];
  EXPECT_EQ(b.id, 3u);
  EXPECT_EQ(b.kind, SurfaceKind::kFloor);
  EXPECT_NEAR((b.plane.n - w.plane.n).norm(), 0.0, 1e-12);
  ASSERT_EQ(b.extent_uv_m.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR((b.corner(i) - w.corner(i)).norm(), 0.0, 1e-9);
  EXPECT_NEAR(b.u.cross(b.v).dot(b.plane.n), 1.0, 1e-12);  // u x v = n

  nlohmann::json bad = firmware::to_json(room);
  bad["surfaces"][0]["extent"][2] = {2.5, 1.5, 0.0};  // 0.9 m off the plane
  try {
    (void)firmware::walls_from_json(bad, "walls.json");
    FAIL() << "accepted a corner off the plane";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("walls.json: surface 0: extent corner off"));
  }
}

// The bundled EuRoC cut: through the appliance (lock step), the floor its reconstruction found,
// drawn on llvmpipe as `wallar render` draws it. The floor overlay
// must cover the pixels where the map's floor points project (where the floor is), fill much
// of the lower image and stay out of the upper. Its PNGs are kept in
// <build>/test_artifacts/euroc_view (checked by eye: the overlay lies on the floor's pattern).
TEST(HeadsetViewEuroc, TheFloorOverlayCoversTheFloorInTheImage) {
  const recording::EurocRecording rec = recording::read_euroc(bundled_recording());
  std::atomic<bool> stop{false};
  const firmware::ApplianceReport report = firmware::run_over_recording(
      rec, firmware::BoardConfig{}, firmware::offline_options(firmware::ApplianceMode::kLockStep),
      stop);
  firmware::RunEvaluationOptions eval_options;
  eval_options.gravity_aligned = true;
  const firmware::RunOutputs track = firmware::evaluate_run(rec, report, eval_options).outputs;
  ASSERT_TRUE(track.room.has_value());
  const dsp::RoomResult& room = *track.room;
  WallModel floor_only;
  for (const Wall& w : room.model.walls) {
    if (w.kind == SurfaceKind::kFloor) floor_only.walls.push_back(w);
  }
  ASSERT_EQ(floor_only.walls.size(), 1u);
  const Wall& floor = floor_only.walls[0];

  const RigCalibration rig = rec.rig();
  const int w = rig.cams[0].width_px, h = rig.cams[0].height_px;
  firmware::HeadsetViewOptions view_options;
  view_options.display.width_px = 2 * w;  // one display pixel per camera pixel
  view_options.display.height_px = h;
  view_options.renderer.hud = false;
  view_options.png_dir = fs::path(WALLAR_BINARY_DIR) / "test_artifacts" / "euroc_view";
  firmware::HeadsetView view(rig, view_options);

  StereoFrame pair;
  pair.t_ns = report.trajectory[0].t_ns;
  pair.left.image = recording::load_png_gray(rec.cams[0].image_path(rec.cams[0].frames[0]));
  pair.right.image = recording::load_png_gray(rec.cams[1].image_path(rec.cams[1].frames[0]));
  ASSERT_EQ(track.poses[0].t_ns, rec.cams[0].frames[0].t_ns);
  const SE3d& T_world_body = track.poses[0].T_world_body;
  // Drawn without and with the floor: the difference is the overlay.
  ASSERT_TRUE(view.show(pair, 0, T_world_body, true, nullptr, {}));
  ASSERT_TRUE(view.show(pair, 0, T_world_body, true, &floor_only, {}));
  ASSERT_EQ(view.stats().written, 2u);
  const Image plain = recording::load_png_rgb(view.stats().written_files[0]);
  const Image drawn = recording::load_png_rgb(view.stats().written_files[1]);
  const cv::Mat a(plain.height(), plain.width(), CV_8UC3, const_cast<std::uint8_t*>(plain.data()),
                  plain.stride_bytes());
  const cv::Mat b(drawn.height(), drawn.width(), CV_8UC3, const_cast<std::uint8_t*>(drawn.data()),
                  drawn.stride_bytes());
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  cv::cvtColor(diff, diff, cv::COLOR_RGB2GRAY);
  const cv::Mat overlay = diff(cv::Rect(0, 0, w, h)) > 4;  // the left eye

  // Where the floor is: the map's floor inliers seen by the left camera in this frame.
  const SE3d T_cam_world = (T_world_body * rig.cams[0].T_body_cam).inverse();
  int seen = 0, covered = 0, lowest_row = 0;
  for (std::size_t i = 0; i < track.map.size(); ++i) {
    const Eigen::Vector3d p(track.map.x[i], track.map.y[i], track.map.z[i]);
    if (std::abs(floor.plane.signed_distance(p)) > 0.04) continue;
    const Eigen::Vector3d q = T_cam_world * p;
    if (q.z() < 0.1) continue;
    // Ideal (undistorted) pixel: the view shows the undistorted image.
    const double u = rig.cams[0].fx * q.x() / q.z() + rig.cams[0].cx;
    const double v = rig.cams[0].fy * q.y() / q.z() + rig.cams[0].cy;
    if (u < 2 || v < 2 || u > w - 3 || v > h - 3) continue;
    ++seen;
    lowest_row = std::max(lowest_row, static_cast<int>(v));
    // Within 2 px: the overlay is the extent's hull, the point may sit on its edge.
    const cv::Rect around(static_cast<int>(u) - 2, static_cast<int>(v) - 2, 5, 5);
    covered += cv::countNonZero(overlay(around)) > 0 ? 1 : 0;
  }
  ASSERT_GT(seen, 50) << "floor points in view";
  EXPECT_GT(covered, seen * 95 / 100) << covered << " of " << seen << " floor points covered";
  // The floor is the lower part of this view (the camera looks down at it): the overlay (the
  // hull of the mapped floor) fills much of the lower half and stays off the upper third, where
  // the walls and the window are.
  const cv::Mat lower = overlay(cv::Rect(0, h / 2, w, h - h / 2));
  EXPECT_GT(cv::countNonZero(lower), static_cast<int>(lower.total() * 3 / 10));
  const cv::Mat upper = overlay(cv::Rect(0, 0, w, h / 3));
  EXPECT_LT(cv::countNonZero(upper), static_cast<int>(upper.total() / 100));

  // Camera lost (video see-through): the last image, frozen, is drawn dark red and the floor
  // is not drawn over it, whatever the pose says.
  display::HudState lost;
  lost.image_frozen = true;
  ASSERT_TRUE(view.show(pair, 0, T_world_body, true, &floor_only, lost));
  const Image frozen_image = recording::load_png_rgb(view.stats().written_files[2]);
  const cv::Mat f(frozen_image.height(), frozen_image.width(), CV_8UC3,
                  const_cast<std::uint8_t*>(frozen_image.data()), frozen_image.stride_bytes());
  const cv::Scalar live_mean = cv::mean(a(cv::Rect(0, 0, w, h)));
  const cv::Scalar frozen_mean = cv::mean(f(cv::Rect(0, 0, w, h)));
  EXPECT_NEAR(frozen_mean[0], 0.40 * live_mean[0], 2.0);  // R at 40 %
  EXPECT_NEAR(frozen_mean[1], 0.08 * live_mean[1], 2.0);  // G and B at 8 %
  EXPECT_NEAR(frozen_mean[2], 0.08 * live_mean[2], 2.0);
  // Where the floor overlay was, the frozen image alone: no wall colour.
  std::vector<cv::Mat> live_rgb, frozen_rgb;
  cv::split(a(cv::Rect(0, 0, w, h)), live_rgb);
  cv::split(f(cv::Rect(0, 0, w, h)), frozen_rgb);
  cv::Mat expected_r;
  live_rgb[0].convertTo(expected_r, CV_8U, 0.40);
  cv::Mat off;
  cv::absdiff(frozen_rgb[0], expected_r, off);
  EXPECT_LT(cv::countNonZero((off > 3) & overlay),
            static_cast<int>(cv::countNonZero(overlay) / 100))
      << "the floor drawn over a frozen image";
}

// The visualization thread never holds the poster up: 60 frames posted back to back (much
// faster than llvmpipe draws) are each drawn or counted as skipped, the newest is drawn last,
// and every drawn frame has a latency from its capture time.
TEST(LiveView, DrawsTheNewestFrameAndCountsTheSkippedOnes) {
  const RigCalibration rig = small_rig();
  firmware::HeadsetViewOptions options;
  options.display.width_px = 64;
  options.display.height_px = 32;
  firmware::LiveView live(rig, options, WallModel{}, 20.0);
  for (int i = 0; i < 60; ++i) {
    firmware::ViewPost post;
    post.frame.t_ns = i;
    post.frame.left.image =
        Image::allocate(rig.cams[0].width_px, rig.cams[0].height_px, PixelFormat::kGray8);
    post.frame.right.image = post.frame.left.image;
    post.capture_t_ns = monotonic_now_ns();
    post.state = dsp::TrackingState::kTracking;
    live.post(std::move(post));
  }
  const firmware::LiveViewStats s = live.stop();
  EXPECT_EQ(s.posted, 60u);
  EXPECT_EQ(s.view.frames + s.skipped, 60u);
  EXPECT_GE(s.view.frames, 1u);
  EXPECT_EQ(s.view.last_t_ns, 59);  // the newest
  EXPECT_EQ(s.view.latency_ns.size(), s.view.frames);
  for (const std::int64_t l : s.view.latency_ns) EXPECT_GT(l, 0);
}

/// A real headless output whose present() fails once, like a display unplugged mid-run.
class FlakyOutput final : public display::DisplayOutput {
 public:
  FlakyOutput(std::unique_ptr<display::DisplayOutput> real, int fail_at)
      : real_(std::move(real)), fail_at_(fail_at) {}
  int width_px() const override { return real_->width_px(); }
  int height_px() const override { return real_->height_px(); }
  std::string describe() const override { return "flaky " + real_->describe(); }
  bool present(TimeNs& t_ns) override {
    if (++presents_ == fail_at_) {
      error_ = "connector unplugged (test)";
      return false;
    }
    return real_->present(t_ns);
  }
  void read_pixels(std::span<std::uint8_t> rgba) override { real_->read_pixels(rgba); }
  const std::string& last_error() const override { return error_; }

 private:
  std::unique_ptr<display::DisplayOutput> real_;
  int fail_at_;
  int presents_ = 0;
  std::string error_;
};

// A lost output is re-opened and drawing goes on; tracking never waited for it.
TEST(LiveView, ALostDisplayIsReopenedAndDrawingGoesOn) {
  const RigCalibration rig = small_rig();
  firmware::HeadsetViewOptions options;
  options.display.width_px = 64;
  options.display.height_px = 32;
  std::atomic<int> opens{0};
  options.open =
      [&opens](const display::DisplayOptions& d) -> std::unique_ptr<display::DisplayOutput> {
    // The first output fails at its third frame; the second never does.
    return std::make_unique<FlakyOutput>(display::open_display(d), ++opens == 1 ? 3 : -1);
  };
  firmware::LiveView live(rig, options, WallModel{}, 20.0);
  for (std::uint64_t i = 0; i < 6; ++i) {
    firmware::ViewPost post;
    post.frame.t_ns = static_cast<TimeNs>(i);
    post.frame.left.image =
        Image::allocate(rig.cams[0].width_px, rig.cams[0].height_px, PixelFormat::kGray8);
    post.frame.right.image = post.frame.left.image;
    post.state = dsp::TrackingState::kTracking;
    live.post(std::move(post));
    // One at a time: wait (bounded) until the renderer has taken it.
    for (int k = 0; k < 500 && live.attempts() <= i; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ASSERT_EQ(live.attempts(), i + 1) << "frame " << i << " was not taken";
  }
  const firmware::LiveViewStats s = live.stop();
  EXPECT_EQ(opens.load(), 2);
  EXPECT_EQ(s.losses, 1u);
  EXPECT_EQ(s.reopens, 1u);
  EXPECT_EQ(s.view.frames, 6u);
  EXPECT_EQ(s.view.present_failures, 1u);
  EXPECT_EQ(s.view.render_ns.size(), 5u);
  EXPECT_EQ(s.view.last_t_ns, 5);
  EXPECT_EQ(s.skipped, 0u);
}

TEST(LiveView, ADisplayThatCannotOpenIsAnErrorAtStart) {
  firmware::HeadsetViewOptions options;
  options.display.backend = display::DisplayBackend::kKms;
  options.display.card = "/nonexistent/card0";
  EXPECT_THROW(firmware::LiveView(small_rig(), options, WallModel{}, 20.0), display::DisplayError);
}

}  // namespace
}  // namespace wallar::test
