// SPDX-License-Identifier: Apache-2.0
/// @file bench_render.cpp
/// @brief The headset view per stereo frame on the headless EGL output (Mesa llvmpipe here):
/// two 752x480 camera images with EuRoC's distortion, undistorted in the shader, a six-surface
/// room with outlines, floor grid and HUD, 1280x720 side by side, finished (glFinish) each
/// frame. The peer: the same picture composed on the CPU with OpenCV (cv::remap with
/// precomputed maps, cv::fillConvexPoly + cv::addWeighted, cv::polylines), one thread.
///
/// Threading: benchmark thread only.
#include <benchmark/benchmark.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "wallar/drivers/display/display_output.hpp"
#include "wallar/drivers/display/headset_renderer.hpp"

namespace {

using namespace wallar;
using namespace wallar::display;

constexpr int kW = 752, kH = 480;

EyeCamera euroc_cam0() {
  EyeCamera c;
  c.width_px = kW;
  c.height_px = kH;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.radtan = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return c;
}

Image textured() {
  Image img = Image::allocate(kW, kH, PixelFormat::kGray8);
  cv::Mat m(kH, kW, CV_8U, img.mutable_data(), img.stride_bytes());
  cv::randu(m, 0, 255);
  cv::GaussianBlur(m, m, cv::Size(5, 5), 1.5);
  return img;
}

/// A 4 x 5 x 2.5 m room around the viewer (y down), as six surfaces facing inwards.
WallModel room() {
  WallModel model;
  const double x0 = -2.0, x1 = 2.0, y0 = -1.0, y1 = 1.5, z0 = -1.0, z1 = 4.0;
  auto add = [&](std::uint32_t id, SurfaceKind kind, Eigen::Vector3d n, double d,
                 Eigen::Vector3d origin, Eigen::Vector3d u, double u_len, double v_len) {
    Wall w;
    w.id = id;
    w.kind = kind;
    w.plane.n = n;
    w.plane.d = d;
    w.origin = origin;
    w.u = u;
    w.v = n.cross(u);
    w.extent_uv_m = {{0.0, 0.0}, {u_len, 0.0}, {u_len, v_len}, {0.0, v_len}};
    model.walls.push_back(w);
  };
  // n.p - d = 0 with n toward the viewer at the origin.
  add(1, SurfaceKind::kWall, {0, 0, -1}, -z1, {x0, y0, z1}, {1, 0, 0}, x1 - x0, y1 - y0);
  add(2, SurfaceKind::kWall, {0, 0, 1}, z0, {x1, y0, z0}, {-1, 0, 0}, x1 - x0, y1 - y0);
  add(3, SurfaceKind::kWall, {1, 0, 0}, x0, {x0, y0, z0}, {0, 0, 1}, z1 - z0, y1 - y0);
  add(4, SurfaceKind::kWall, {-1, 0, 0}, -x1, {x1, y0, z1}, {0, 0, -1}, z1 - z0, y1 - y0);
  add(5, SurfaceKind::kFloor, {0, -1, 0}, -y1, {x0, y1, z1}, {1, 0, 0}, x1 - x0, z1 - z0);
  add(6, SurfaceKind::kCeiling, {0, 1, 0}, y0, {x0, y0, z0}, {1, 0, 0}, x1 - x0, z1 - z0);
  return model;
}

void BM_RenderStereoFrame(benchmark::State& state) {
  DisplayOptions d;
  d.width_px = 1280;
  d.height_px = 720;
  const auto output = open_display(d);
  RendererOptions o;
  o.lens_k1 = state.range(0) != 0 ? 0.22 : 0.0;
  o.lens_k2 = state.range(0) != 0 ? 0.24 : 0.0;
  HeadsetRenderer renderer(*output, o);
  const WallModel model = room();
  HeadsetFrame f;
  for (int eye = 0; eye < 2; ++eye) {
    f.eyes[eye].camera = euroc_cam0();
    f.eyes[eye].image = textured();
    f.eyes[eye].T_world_cam.translation() = Eigen::Vector3d(0.11 * eye, 0.0, 0.0);
  }
  f.walls = &model;
  f.hud.fps = 20.0;
  f.hud.walls = 6;
  for (auto _ : state) {
    const RenderTiming t = renderer.draw(f);
    if (!t.presented) state.SkipWithError(output->last_error().c_str());
  }
  state.SetLabel(output->describe());
}
BENCHMARK(BM_RenderStereoFrame)->Arg(0)->Arg(1)->ArgName("lens")->Unit(benchmark::kMillisecond);

void BM_OpenCvCompositeStereoFrame(benchmark::State& state) {
  cv::setNumThreads(1);
  const EyeCamera c = euroc_cam0();
  const cv::Matx33d K(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  const std::vector<double> dist(c.radtan.begin(), c.radtan.end());
  // 752x480 eyes scaled into 640x409 halves of 1280x720, maps precomputed once.
  const cv::Size eye(640, 409);
  const cv::Matx33d K_out(c.fx * 640.0 / kW, 0, (c.cx + 0.5) * 640.0 / kW - 0.5, 0,
                          c.fy * 409.0 / kH, (c.cy + 0.5) * 409.0 / kH - 0.5, 0, 0, 1);
  cv::Mat map1, map2;
  cv::initUndistortRectifyMap(K, dist, cv::Mat(), K_out, eye, CV_16SC2, map1, map2);
  const Image img = textured();
  const cv::Mat src(kH, kW, CV_8U, const_cast<std::uint8_t*>(img.data()), img.stride_bytes());
  const WallModel model = room();
  cv::Mat canvas(720, 1280, CV_8UC3), gray(eye, CV_8U), fill;
  for (auto _ : state) {
    canvas.setTo(0);
    for (int e = 0; e < 2; ++e) {
      cv::remap(src, gray, map1, map2, cv::INTER_LINEAR);
      cv::Mat roi = canvas(cv::Rect(e * 640, (720 - 409) / 2, 640, 409));
      cv::cvtColor(gray, roi, cv::COLOR_GRAY2BGR);
      roi.copyTo(fill);
      for (const Wall& w : model.walls) {
        std::vector<cv::Point> poly;
        for (std::size_t k = 0; k < w.extent_uv_m.size(); ++k) {
          Eigen::Vector3d p = w.corner(k) - Eigen::Vector3d(0.11 * e, 0, 0);
          if (p.z() < 0.05) p.z() = 0.05;  // (no near-plane clipping: the peer's shortcut)
          poly.emplace_back(static_cast<int>(K_out(0, 0) * p.x() / p.z() + K_out(0, 2)),
                            static_cast<int>(K_out(1, 1) * p.y() / p.z() + K_out(1, 2)));
        }
        const auto rgb = surface_colour_rgb(w.id);
        cv::fillConvexPoly(fill, poly, cv::Scalar(rgb[2], rgb[1], rgb[0]));
        cv::polylines(roi, poly, true, cv::Scalar(rgb[2], rgb[1], rgb[0]), 2);
      }
      cv::addWeighted(roi, 0.65, fill, 0.35, 0.0, roi);
    }
    cv::putText(canvas, "tracking  20.0 fps  6 walls", cv::Point(20, 40), cv::FONT_HERSHEY_SIMPLEX,
                0.8, cv::Scalar(255, 255, 255), 2, cv::LINE_AA);
    benchmark::DoNotOptimize(canvas.data);
  }
  state.SetLabel("OpenCV, 1 thread, CPU");
}
BENCHMARK(BM_OpenCvCompositeStereoFrame)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
