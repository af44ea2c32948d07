// SPDX-License-Identifier: Apache-2.0
/// @file cmd_eval_marker.cpp
/// @brief `wallar eval marker`: wall ground truth from an ArUco marker (tools/eval/marker.hpp).
/// Three modes: --image (the marker's plane in one image), --study (accuracy on rendered views
/// of known pose), --render (write such a view, for users and tests).
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/eval/marker.hpp"
#include "wallar/eval/output.hpp"

namespace wallar::cli {
namespace {

struct MarkerArgs {
  std::string image;
  bool study = false;
  bool render = false;
  std::string recording;
  std::string camera = "cam0";
  eval::MarkerSpec spec;
  std::string out;
  double distance_m = -1.0;
  double angle_deg = 0.0;
  double noise_sigma = 2.0;
  std::uint64_t seed = 1;
  int seeds = 5;
  bool json = false;
};

nlohmann::json pose_json(const Eigen::Isometry3d& T) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    rows.push_back({T.matrix()(r, 0), T.matrix()(r, 1), T.matrix()(r, 2), T.matrix()(r, 3)});
  }
  return rows;
}

nlohmann::json plane_json(const Plane& plane) {
  return {{"n", {plane.n.x(), plane.n.y(), plane.n.z()}}, {"d", plane.d}};
}

std::string vec_text(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(5) << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return s.str();
}

CameraCalibration camera_of(const MarkerArgs& a) {
  recording::ReadOptions options;
  options.check_image_files = false;
  const recording::EurocRecording rec = read_recording_reporting(a.recording, options);
  return rec.cams[a.camera == "cam1" ? 1 : 0].calib;
}

int run_image(const MarkerArgs& a, const CameraCalibration& cam) {
  const Image gray = recording::load_png_gray(a.image, cam.width_px, cam.height_px);
  const auto est = eval::estimate_marker_plane(gray, cam, a.spec);
  if (!est) {
    std::fprintf(stderr, "wallar: no ArUco marker %s id %d found in %s\n",
                 a.spec.dictionary.c_str(), a.spec.id, a.image.c_str());
    return kExitFailure;
  }
  const Eigen::Vector3d centre = est->T_cam_marker.translation();
  if (a.json) {
    const nlohmann::json out{
        {"image", a.image},
        {"camera", cam.name},
        {"marker", {{"dictionary", a.spec.dictionary}, {"id", est->id}, {"size_m", a.spec.size_m}}},
        {"plane", plane_json(est->plane)},
        {"distance_m", centre.norm()},
        {"plane_distance_m", -est->plane.d},
        {"T_cam_marker", pose_json(est->T_cam_marker)},
        {"reprojection_rms_px", est->reprojection_rms_px}};
    std::cout << out.dump(2) << "\n";
    return kExitOk;
  }
  std::ostringstream text;
  text << "wallar eval marker: " << a.spec.dictionary << " id " << est->id << " ("
       << a.spec.size_m * 1000.0 << " mm) in " << a.image << ", " << cam.name << "\n"
       << "plane (camera frame, n toward the camera): n = " << vec_text(est->plane.n) << std::fixed
       << std::setprecision(4) << ", d = " << est->plane.d << " m\n"
       << "distance: marker centre " << centre.norm() << " m, plane " << -est->plane.d << " m\n"
       << "T_cam_marker:\n";
  for (int r = 0; r < 4; ++r) {
    text << "  ";
    for (int c = 0; c < 4; ++c) {
      text << std::setw(10) << est->T_cam_marker.matrix()(r, c) << (c < 3 ? " " : "\n");
    }
  }
  text << "reprojection rms: " << est->reprojection_rms_px << " px\n";
  std::cout << text.str();
  return kExitOk;
}

int run_render(const MarkerArgs& a, const CameraCalibration& cam) {
  const Eigen::Isometry3d T_cam_marker = eval::marker_view_pose(a.distance_m, a.angle_deg);
  const Image image = eval::render_marker_view(cam, T_cam_marker, a.spec, a.noise_sigma, a.seed);
  recording::save_png_gray(a.out, image);
  const Plane plane = eval::marker_plane(T_cam_marker);
  if (a.json) {
    const nlohmann::json out{
        {"image", a.out},
        {"camera", cam.name},
        {"marker",
         {{"dictionary", a.spec.dictionary}, {"id", a.spec.id}, {"size_m", a.spec.size_m}}},
        {"distance_m", a.distance_m},
        {"angle_deg", a.angle_deg},
        {"seed", a.seed},
        {"plane", plane_json(plane)},
        {"T_cam_marker", pose_json(T_cam_marker)}};
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << "wallar eval marker: rendered " << a.out << " (" << cam.name << ", "
              << a.distance_m << " m, " << a.angle_deg
              << " deg): true plane n = " << vec_text(plane.n) << ", d = " << plane.d << " m\n";
  }
  return kExitOk;
}

int run_study(const MarkerArgs& a, const CameraCalibration& cam) {
  eval::OutputDir out(a.out.empty() ? std::string("eval_marker") : a.out,
                      eval::gnuplot_available());
  eval::MarkerStudyOptions options;
  options.spec = a.spec;
  options.seed = a.seed;
  options.noise_sigma = a.noise_sigma;
  options.seeds = a.seeds;
  const nlohmann::json summary = eval::run_marker_study(options, cam, out);
  if (!out.plots()) {
    std::fprintf(stderr, "wallar: gnuplot not found: wrote marker_accuracy.gp, no PNG\n");
  }
  if (a.json) {
    std::cout << summary.dump(2) << "\n";
    return kExitOk;
  }
  const auto show = [](const nlohmann::json& s) {
    std::ostringstream t;
    t << std::setprecision(3) << s["found"].get<int>() << "/" << s["views"].get<int>() << " found";
    if (!s["median_normal_error_deg"].is_null()) {
      t << ", median normal " << s["median_normal_error_deg"].get<double>() << " deg, offset "
        << s["median_offset_error_m"].get<double>() * 1000.0 << " mm; max normal "
        << s["max_normal_error_deg"].get<double>() << " deg, offset "
        << s["max_offset_error_m"].get<double>() * 1000.0 << " mm";
    }
    return t.str();
  };
  std::cout << "wallar eval marker --study: " << summary["views"] << " views, " << summary["found"]
            << " found, into " << out.path().string() << "\n"
            << "  within 1 m and 45 deg: " << show(summary["within_1m_45deg"]) << "\n"
            << "  at 3 m and 60 deg:     " << show(summary["at_3m_60deg"]) << "\n"
            << "  (thesis, ARToolKit 177 mm within 1 m and 45 deg: ~0.5 deg, ~3 mm)\n";
  return kExitOk;
}

int run_marker_command(const MarkerArgs& a) {
  const int modes = (a.image.empty() ? 0 : 1) + (a.study ? 1 : 0) + (a.render ? 1 : 0);
  if (modes != 1) {
    throw CLI::ValidationError("marker", "give exactly one of --image FILE, --study, --render");
  }
  if (a.render && (a.distance_m <= 0.0 || a.out.empty())) {
    throw CLI::ValidationError("--render", "needs --distance-m D and --out FILE.png");
  }
  if (!eval::aruco_available()) {
    throw std::runtime_error(
        "ArUco marker support is not in this build (OpenCV contrib is host-only)");
  }
  eval::check_marker_spec(a.spec);
  const CameraCalibration cam = camera_of(a);
  if (a.render) return run_render(a, cam);
  if (a.study) return run_study(a, cam);
  return run_image(a, cam);
}

}  // namespace

void add_eval_marker_command(CLI::App& eval, std::function<int()>& run) {
  auto a = std::make_shared<MarkerArgs>();
  CLI::App* cmd = eval.add_subcommand(
      "marker",
      "Wall ground truth from an ArUco marker: one image, an accuracy study, or a render");
  cmd->add_option("--image", a->image, "Gray PNG to find the marker in (the camera's size)");
  cmd->add_flag("--study", a->study,
                "Accuracy on rendered views at 0.4-3 m and 0-60 deg into --out DIR");
  cmd->add_flag("--render", a->render,
                "Write a rendered view (--distance-m, --angle-deg) to --out FILE.png");
  cmd->add_option("--recording", a->recording,
                  "Recording (EuRoC folder or .mcap) whose calibration to use")
      ->required();
  cmd->add_option("--camera", a->camera, "Which camera's calibration")
      ->check(CLI::IsMember({"cam0", "cam1"}))
      ->capture_default_str();
  cmd->add_option("--size-m", a->spec.size_m, "Side of the marker's black square [m]")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--dictionary", a->spec.dictionary,
                  "ArUco dictionary: 4X4_50 ... 7X7_1000, ARUCO_ORIGINAL, APRILTAG_36h11 ...")
      ->capture_default_str();
  cmd->add_option("--id", a->spec.id, "Marker id")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--out", a->out,
                  "--study: result folder (default eval_marker); --render: the PNG to write");
  cmd->add_option("--distance-m", a->distance_m, "--render: marker centre distance [m]")
      ->check(CLI::Range(0.05, 100.0));
  cmd->add_option("--angle-deg", a->angle_deg, "--render: viewing angle [deg]")
      ->check(CLI::Range(0.0, 85.0))
      ->capture_default_str();
  cmd->add_option("--noise", a->noise_sigma, "--render, --study: image noise sigma [gray levels]")
      ->check(CLI::Range(0.0, 50.0))
      ->capture_default_str();
  cmd->add_option("--seed", a->seed, "--render, --study: (first) random seed")
      ->capture_default_str();
  cmd->add_option("--seeds", a->seeds, "--study: renders per distance and angle")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_flag("--json", a->json, "Print the result as JSON");
  cmd->callback([a, &run] { run = [a] { return run_marker_command(*a); }; });
}

}  // namespace wallar::cli
