// SPDX-License-Identifier: Apache-2.0
/// @file real.cpp
/// @brief The room in a real recording: sparse stereo map, gravity-aligned room search, the
/// floor against IMU and ground-truth gravity, and an overlay on the first left image.
#include "wallar/eval/real.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/imu/static_init.hpp"
#include "wallar/dsp/stereo/sparse_stereo.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/dsp/walls/room_check.hpp"

namespace wallar::eval {
namespace {

// Most surfaces searched for in a sparse map: the floor and what the camera faces.
constexpr int kMaxSurfaces = 4;

// Collects the recording's stereo pairs (times and frame indices only, no pixels).
class PairLister final : public source::SensorSink {
 public:
  void on_imu(const ImuSample&) override {}
  void on_stereo(const StereoFrame& f) override { pairs.push_back(f); }
  std::vector<StereoFrame> pairs;
};

double ms_since(TimeNs t0_ns) { return static_cast<double>(monotonic_now_ns() - t0_ns) * 1e-6; }

nlohmann::json vec_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json optional_json(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

// Names of the surfaces as the CSV and the legend give them: floor, ceiling, wall_1, wall_2...
std::vector<std::string> surface_names(const dsp::RoomResult& room) {
  std::vector<std::string> names;
  int walls = 0;
  for (const auto& s : room.surfaces) {
    names.push_back(s.wall.kind == SurfaceKind::kWall ? "wall_" + std::to_string(++walls)
                                                      : std::string(to_string(s.wall.kind)));
  }
  return names;
}

cv::Scalar colour(const std::array<std::uint8_t, 3>& rgb) {
  return {static_cast<double>(rgb[0]), static_cast<double>(rgb[1]), static_cast<double>(rgb[2])};
}

struct OverlayLegend {
  std::string title;
  std::vector<std::string> surface_lines;  //!< one per room surface
  std::string floor_line;                  //!< empty when there is no floor check
};

// The first left image in colour (RGB), map points projected into the raw image with the
// camera's own distortion, each surface's points in its colour, the floor's outline, a legend.
Image draw_overlay(const Image& left, const CameraCalibration& cam, const PointCloud& map,
                   const std::vector<int>& surface, const dsp::RoomResult& room,
                   const OverlayLegend& legend) {
  Image rgb = Image::allocate(left.width(), left.height(), PixelFormat::kRgb8);
  cv::Mat canvas(rgb.height(), rgb.width(), CV_8UC3, rgb.mutable_data(),
                 static_cast<std::size_t>(rgb.stride_bytes()));
  const cv::Mat gray(left.height(), left.width(), CV_8UC1, const_cast<std::uint8_t*>(left.data()),
                     static_cast<std::size_t>(left.stride_bytes()));
  cv::Mat dimmed;
  gray.convertTo(dimmed, CV_8UC1, 0.75);  // coloured points stand out on a darker image
  cv::cvtColor(dimmed, canvas, cv::COLOR_GRAY2RGB);

  // Project the points in front of the camera (the map is in this camera's frame).
  std::vector<cv::Point3f> in_front;
  std::vector<std::size_t> index;
  for (std::size_t i = 0; i < map.size(); ++i) {
    if (map.z[i] > 0.0f) {
      in_front.emplace_back(map.x[i], map.y[i], map.z[i]);
      index.push_back(i);
    }
  }
  std::vector<cv::Point2f> px;
  if (!in_front.empty()) {
    const cv::Matx33d K(cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0);
    cv::projectPoints(in_front, cv::Vec3d::all(0.0), cv::Vec3d::all(0.0), K, cam.distortion, px);
  }
  const cv::Rect frame(0, 0, canvas.cols, canvas.rows);
  // Points on no surface first, small and gray; then each surface's, on top.
  for (std::size_t k = 0; k < px.size(); ++k) {
    if (surface[index[k]] < 0 && frame.contains(px[k])) {
      cv::circle(canvas, px[k], 1, colour(dsp::kNoSurfaceRgb), cv::FILLED, cv::LINE_AA);
    }
  }
  std::vector<cv::Point2f> floor_px;
  std::uint32_t floor_id = 0;
  for (std::size_t k = 0; k < px.size(); ++k) {
    const int s = surface[index[k]];
    if (s < 0 || !frame.contains(px[k])) continue;
    const Wall& wall = room.surfaces[static_cast<std::size_t>(s)].wall;
    cv::circle(canvas, px[k], 2, colour(dsp::surface_colour_rgb(wall.id)), cv::FILLED, cv::LINE_AA);
    if (wall.kind == SurfaceKind::kFloor) {
      floor_px.push_back(px[k]);
      floor_id = wall.id;
    }
  }
  // The floor's outline: the convex hull of its points' projections, white under its colour.
  if (floor_px.size() >= 3) {
    std::vector<cv::Point2f> hull_f;
    cv::convexHull(floor_px, hull_f);
    std::vector<cv::Point> hull;
    for (const auto& p : hull_f) hull.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(canvas, hull, true, cv::Scalar(255, 255, 255), 4, cv::LINE_AA);
    cv::polylines(canvas, hull, true, colour(dsp::surface_colour_rgb(floor_id)), 2, cv::LINE_AA);
  }
  // Legend, top left, on a dark box.
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const double scale = 0.42;
  const int line_px = 17;
  std::vector<std::pair<std::string, cv::Scalar>> lines;
  lines.emplace_back(legend.title, cv::Scalar(255, 255, 255));
  for (std::size_t i = 0; i < room.surfaces.size(); ++i) {
    lines.emplace_back(legend.surface_lines[i],
                       colour(dsp::surface_colour_rgb(room.surfaces[i].wall.id)));
  }
  lines.emplace_back("none (on no surface)", colour(dsp::kNoSurfaceRgb));
  if (!legend.floor_line.empty()) lines.emplace_back(legend.floor_line, cv::Scalar(255, 255, 255));
  int width_px = 0;
  for (const auto& l : lines) {
    int baseline = 0;
    width_px = std::max(width_px, cv::getTextSize(l.first, font, scale, 1, &baseline).width);
  }
  const cv::Rect box(4, 4, std::min(width_px + 30, canvas.cols - 8),
                     std::min(static_cast<int>(lines.size()) * line_px + 8, canvas.rows - 8));
  cv::Mat roi = canvas(box);
  roi.convertTo(roi, -1, 0.35);  // darken behind the text
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const int y = box.y + 4 + static_cast<int>(i + 1) * line_px - 4;
    const bool swatch = i > 0 && (i <= room.surfaces.size() + 1);
    if (swatch) {
      cv::rectangle(canvas, cv::Rect(box.x + 6, y - 10, 12, 10), lines[i].second, cv::FILLED);
    }
    cv::putText(canvas, lines[i].first, cv::Point(box.x + (swatch ? 24 : 6), y), font, scale,
                swatch ? cv::Scalar(255, 255, 255) : lines[i].second, 1, cv::LINE_AA);
  }
  return rgb;
}

}  // namespace

nlohmann::json run_real_study(const RealStudyOptions& options, OutputDir& out) {
  const TimeNs t_start_ns = monotonic_now_ns();
  const std::string where = options.recording.string();
  if (options.pairs < 1) {
    throw_input_error(where, 0, "--pairs must be at least 1, got " + std::to_string(options.pairs));
  }
  if (!(options.threshold_m > 0.0) || !std::isfinite(options.threshold_m)) {
    throw_input_error(where, 0, "--threshold-m must be a positive number of metres");
  }
  const recording::EurocRecording rec = recording::read_recording(options.recording);

  // The stereo pairs, paired as replay pairs them (tolerance: half a frame period).
  source::ReplayOptions list_options;
  list_options.rate = 0.0;
  list_options.with_images = false;
  PairLister lister;
  const std::atomic<bool> never_stop{false};
  source::ReplaySource(rec, list_options).run(lister, never_stop);
  const std::vector<StereoFrame>& all = lister.pairs;
  const bool orb = options.map_source == RealMapSource::kOrb;
  const auto wanted = static_cast<std::size_t>(options.pairs);
  if (orb && all.size() < wanted) {
    throw_input_error((rec.cams[0].dir / "data.csv").string(), 0,
                      "has " + std::to_string(all.size()) + " stereo pairs, the study asks for " +
                          std::to_string(wanted) + " (--pairs)");
  }
  if (all.empty()) throw_input_error(where, 0, "the recording has no stereo pairs");
  const auto load_images = [&rec](StereoFrame f) {
    for (int c = 0; c < 2; ++c) {
      const recording::CameraStream& cam = rec.cams[static_cast<std::size_t>(c)];
      CameraFrame& side = c == 0 ? f.left : f.right;
      side.image = recording::load_frame_gray(rec, c, cam.frames[side.sequence]);
    }
    return f;
  };

  // The map's pairs: spread evenly from the first to the last (orb), or the pair of the given
  // map's frame; the first of them is the overlay's.
  std::vector<StereoFrame> chosen;
  GivenMap given;
  double given_ms = 0.0;  // the appliance's run, for its map
  if (orb) {
    for (std::size_t k = 0; k < wanted; ++k) {
      const std::size_t i =
          wanted == 1 ? 0
                      : static_cast<std::size_t>(std::llround(static_cast<double>(k) *
                                                              static_cast<double>(all.size() - 1) /
                                                              static_cast<double>(wanted - 1)));
      chosen.push_back(load_images(all[i]));
    }
  } else {
    if (!options.appliance_map) throw std::logic_error("run_real_study: no appliance map given");
    const TimeNs t_given_ns = monotonic_now_ns();
    given = options.appliance_map(rec);
    given_ms = ms_since(t_given_ns);
    const auto it = std::find_if(all.begin(), all.end(),
                                 [&](const StereoFrame& f) { return f.t_ns == given.t_ns; });
    if (it == all.end()) throw_input_error(where, 0, "the map's frame is not a stereo pair");
    chosen.push_back(load_images(*it));
  }

  // Gravity at rest over the frames' span; "down" in the left camera's frame.
  const auto est = dsp::estimate_static_imu(rec.imu, all.front().t_ns, all.back().t_ns);
  const bool still = est && dsp::is_still(*est);
  const RigCalibration rig = rec.rig();
  const Eigen::Matrix3d R_body_cam = rig.cams[0].T_body_cam.linear();
  std::optional<Eigen::Vector3d> down_cam;
  if (still) down_cam = R_body_cam.transpose() * (-est->mean_accel_m_s2);
  const recording::GroundTruthState* gt = recording::nearest_ground_truth(rec, chosen[0].t_ns);
  std::optional<Eigen::Vector3d> up_cam_gt;
  if (gt != nullptr) up_cam_gt = R_body_cam.transpose() * gt->up_body();

  // The map (left camera frame of the first chosen pair).
  const TimeNs t_map_ns = monotonic_now_ns();
  dsp::SparseMap sparse;
  if (orb) {
    dsp::SparseStereo stereo(rig);
    sparse = dsp::build_sparse_map(stereo, chosen, still);
  } else {
    sparse.points = std::move(given.points);
    sparse.pairs_used = given.frames;
  }
  const double map_ms = orb ? ms_since(t_map_ns) : given_ms;
  const PointCloud& map = sparse.points;
  if (map.size() < 3) {
    throw_input_error(where, 0,
                      "the sparse map has " + std::to_string(map.size()) +
                          " points: too few to search for surfaces (textureless images?)");
  }

  // The room, gravity-aligned when the IMU was at rest.
  dsp::RoomConfig room_cfg;
  room_cfg.detector.threshold_m = options.threshold_m;
  room_cfg.detector.seed = options.seed;
  room_cfg.max_surfaces = kMaxSurfaces;
  room_cfg.gravity = down_cam;
  dsp::RoomEstimator estimator(map.size());
  const TimeNs t_room_ns = monotonic_now_ns();
  const dsp::RoomResult room = estimator.estimate(map, room_cfg);
  const double room_ms = ms_since(t_room_ns);

  const std::vector<int> surface = dsp::surface_of_points(map, room, options.threshold_m);
  const std::vector<std::string> names = surface_names(room);
  std::optional<dsp::FloorCheck> floor;
  if (down_cam) {
    floor = dsp::check_floor(map, room, options.threshold_m, -down_cam->normalized(), up_cam_gt);
  }
  std::optional<double> imu_vs_gt_deg;
  if (est && gt != nullptr) imu_vs_gt_deg = dsp::angle_deg(est->mean_accel_m_s2, gt->up_body());

  // The summary.
  std::vector<std::size_t> labelled(room.surfaces.size(), 0);
  for (const int s : surface) {
    if (s >= 0) ++labelled[static_cast<std::size_t>(s)];
  }
  nlohmann::json surfaces = nlohmann::json::array();
  OverlayLegend legend;
  for (std::size_t i = 0; i < room.surfaces.size(); ++i) {
    const dsp::RoomSurface& s = room.surfaces[i];
    surfaces.push_back({{"name", names[i]},
                        {"id", s.wall.id},
                        {"kind", std::string(to_string(s.wall.kind))},
                        {"normal", vec_json(s.wall.plane.n)},
                        {"d", s.wall.plane.d},
                        {"inliers", s.wall.inliers},
                        {"rmse_m", s.rmse_m},
                        {"map_points", labelled[i]}});
    char line[160];
    std::snprintf(line, sizeof line, "%s: %zu points, %.2f m away, rmse %.1f cm", names[i].c_str(),
                  labelled[i], std::abs(s.wall.plane.d), s.rmse_m * 100.0);
    legend.surface_lines.emplace_back(line);
  }
  nlohmann::json floor_json = nullptr;
  if (floor) {
    floor_json = {
        {"name", names[floor->surface]},
        {"distance_below_camera_m", floor->distance_below_viewer_m},
        {"free_fit_normal", vec_json(floor->free_fit.n)},
        {"free_fit_points", floor->inliers},
        {"free_fit_vs_imu_gravity_deg", floor->free_fit_vs_up_deg},
        {"free_fit_vs_ground_truth_gravity_deg", optional_json(floor->free_fit_vs_up2_deg)}};
    char line[160];
    if (floor->free_fit_vs_up2_deg) {
      std::snprintf(line, sizeof line, "floor fit vs gravity: %.2f deg (IMU), %.2f deg (truth)",
                    floor->free_fit_vs_up_deg, *floor->free_fit_vs_up2_deg);
    } else {
      std::snprintf(line, sizeof line, "floor fit vs IMU gravity: %.2f deg",
                    floor->free_fit_vs_up_deg);
    }
    legend.floor_line = line;
  }
  char title[160];
  std::snprintf(title, sizeof title, "%zu map points from %zu stereo pair%s (%s), %s", map.size(),
                sparse.pairs_used, sparse.pairs_used == 1 ? "" : "s",
                orb ? "ORB matches" : "the appliance's tracker",
                down_cam ? "gravity-aligned" : "3-D (IMU not at rest)");
  legend.title = title;

  nlohmann::json imu = nullptr;
  if (est) {
    imu = {{"samples", est->samples},
           {"still", still},
           {"gravity_norm_m_s2", est->mean_accel_m_s2.norm()},
           {"up_body", vec_json(est->mean_accel_m_s2.normalized())}};
  }
  nlohmann::json summary = {
      {"recording", where},
      {"ground_truth", gt != nullptr},
      {"threshold_m", options.threshold_m},
      {"seed", options.seed},
      {"map_source", orb ? "orb" : "appliance"},
      {"map_description", orb ? std::string("rectified ORB matches") : given.description},
      {"pairs_in_recording", all.size()},
      {"pairs_requested", orb ? nlohmann::json(wanted) : nlohmann::json()},
      {"pairs_used", sparse.pairs_used},
      {"points", map.size()},
      {"gravity_aligned", down_cam.has_value()},
      {"imu", imu},
      {"imu_gravity_vs_ground_truth_deg", optional_json(imu_vs_gt_deg)},
      {"surfaces", surfaces},
      {"rounds", room.rounds},
      {"floor", floor_json},
      {"map_time_ms", map_ms},
      {"room_time_ms", room_ms}};

  // The files: figure and table first, the summary last.
  const Image overlay = draw_overlay(chosen[0].left.image, rig.cams[0], map, surface, room, legend);
  const std::vector<std::uint8_t> png =
      recording::encode_png_rgb(overlay, (out.path() / "real_overlay.png").string());
  out.write("real_overlay.png",
            std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  CsvTable csv({"x", "y", "z", "surface"});
  const auto round_0_1mm = [](float v) { return std::round(static_cast<double>(v) * 1e4) / 1e4; };
  for (std::size_t i = 0; i < map.size(); ++i) {
    csv.add(round_0_1mm(map.x[i])).add(round_0_1mm(map.y[i])).add(round_0_1mm(map.z[i]));
    csv.add(surface[i] < 0 ? std::string_view("none")
                           : std::string_view(names[static_cast<std::size_t>(surface[i])]));
    csv.end_row();
  }
  out.write("real_map.csv", csv.text());
  summary["outputs"] = {"real_overlay.png", "real_map.csv", "real_summary.json"};
  summary["time_ms"] = ms_since(t_start_ns);
  out.write("real_summary.json", summary.dump(2) + "\n");
  return summary;
}

}  // namespace wallar::eval
