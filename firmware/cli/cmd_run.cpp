// SPDX-License-Identifier: Apache-2.0
/// @file cmd_run.cpp
/// @brief `wallar run --board FILE`: the appliance's main job on a board.
///
/// Today's pipeline: the board's source (replay on the sim board) feeds a collector that
/// estimates gravity and gyro bias from the IMU while at rest, checks the estimate against the
/// recording's ground truth when it has one, keeps every 5th stereo pair, maps them (sparse
/// stereo stand-in), finds the walls, draws the headset view of the kept pairs on the board's
/// display (PNGs under --out/view) and writes a summary under --out. The supervisor (issue 9)
/// replaces this sequence with modules on their own threads.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/cloud/cloud_io.hpp"
#include "wallar/dsp/imu/static_init.hpp"
#include "wallar/dsp/stereo/sparse_stereo.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/dsp/walls/room_check.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/headset_view.hpp"
#include "wallar/firmware/report.hpp"
#include "wallar/firmware/source_runner.hpp"

namespace wallar::cli {
namespace {
namespace fs = std::filesystem;

struct RunArgs {
  std::string board;
  std::string out = "out";
  bool json = false;
  bool check = false;
  bool no_view = false;
  int view_every = 1;
  ReplayFlags flags;
};

class CollectorSink final : public source::SensorSink {
 public:
  explicit CollectorSink(std::size_t imu_capacity) {
    imu.reserve(imu_capacity);
    kept.reserve(8);
  }
  void on_imu(const ImuSample& s) override {
    if (imu.size() < imu.capacity()) imu.push_back(s);  // never grow on the sensor thread
  }
  void on_stereo(const StereoFrame& f) override {
    if (pairs == 0) first = f;  // a reference, not a copy of the pixels
    if (pairs % kKeepEvery == 0 && kept.size() < kept.capacity()) kept.push_back(f);
    last_t_ns = f.t_ns;
    ++pairs;
  }
  static constexpr std::uint64_t kKeepEvery = 5;
  std::vector<ImuSample> imu;
  std::vector<StereoFrame> kept;  // pairs for the sparse map
  StereoFrame first;
  TimeNs last_t_ns = 0;
  std::uint64_t pairs = 0;
};

// Inlier band for the stereo sparse map: depth noise of a 11 cm baseline at 2-4 m is
// several centimetres.
constexpr double kMapThresholdM = 0.05;

// Side by side, as the headset's display shows the two eyes.
void save_side_by_side(const fs::path& path, const StereoFrame& f) {
  const Image& l = f.left.image;
  const Image& r = f.right.image;
  if (l.empty() || r.empty() || l.height() != r.height()) return;
  Image sbs = Image::allocate(l.width() + r.width(), l.height(), PixelFormat::kGray8);
  for (int y = 0; y < l.height(); ++y) {
    std::copy_n(l.row(y), l.width(), sbs.mutable_data() + std::ptrdiff_t{y} * sbs.stride_bytes());
    std::copy_n(r.row(y), r.width(),
                sbs.mutable_data() + std::ptrdiff_t{y} * sbs.stride_bytes() + l.width());
  }
  recording::save_png_gray(path, sbs);
}

int run_run_command(const RunArgs& args) {
  const firmware::BoardConfig board = firmware::load_board(args.board);
  if (args.check) {
    std::cout << "board " << board.name << " (" << args.board << "): ok\n";
    return kExitOk;
  }
  if (board.source != firmware::BoardConfig::Source::kReplay) {
    std::fprintf(stderr,
                 "wallar: error: %s: board '%s' uses live sensors; the camera and IMU drivers are "
                 "not in this build yet (use a replay board such as board/sim.yaml)\n",
                 args.board.c_str(), board.name.c_str());
    return kExitFailure;
  }
  const recording::EurocRecording rec = recording::read_euroc(board.replay.recording);
  source::ReplayOptions options;
  options.rate = board.replay.rate;
  options.start_offset_ns = s_to_ns(board.replay.start_offset_s);
  options.skip = board.replay.skip;
  options = args.flags.apply(options);

  std::error_code ec;
  fs::create_directories(args.out, ec);
  if (ec) throw_input_error(args.out, 0, "cannot create output folder: " + ec.message());

  std::cerr << "wallar: board " << board.name << ": replaying " << board.replay.recording.string()
            << " at " << (options.rate > 0 ? std::to_string(options.rate) + "x" : "full speed")
            << "\n";
  CollectorSink sink(rec.imu.size());
  const source::ReplayStats stats = firmware::run_replay(rec, options, sink, stop_requested());

  nlohmann::json summary = {{"board", board.name},
                            {"recording", board.replay.recording.string()},
                            {"replay", firmware::to_json(stats)}};
  std::string text = firmware::to_text(stats);

  // Gravity and gyro bias over the span of the camera frames.
  const auto est = dsp::estimate_static_imu(sink.imu, sink.first.t_ns, sink.last_t_ns);
  if (est && sink.pairs > 0) {
    const bool still = dsp::is_still(*est);
    nlohmann::json imu = {
        {"samples", est->samples},
        {"still", still},
        {"mean_accel_m_s2",
         {est->mean_accel_m_s2.x(), est->mean_accel_m_s2.y(), est->mean_accel_m_s2.z()}},
        {"gravity_norm_m_s2", est->mean_accel_m_s2.norm()},
        {"gyro_bias_rad_s",
         {est->gyro_bias_rad_s.x(), est->gyro_bias_rad_s.y(), est->gyro_bias_rad_s.z()}},
        {"accel_std_m_s2", est->accel_std_m_s2},
        {"gyro_std_rad_s", est->gyro_std_rad_s}};
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "IMU %s over %zu samples: up (body) = (%.4f, %.4f, %.4f) m/s^2, |g| = %.4f; "
                  "gyro bias = (%.5f, %.5f, %.5f) rad/s\n",
                  still ? "at rest" : "MOVING", est->samples, est->mean_accel_m_s2.x(),
                  est->mean_accel_m_s2.y(), est->mean_accel_m_s2.z(), est->mean_accel_m_s2.norm(),
                  est->gyro_bias_rad_s.x(), est->gyro_bias_rad_s.y(), est->gyro_bias_rad_s.z());
    text += buf;
    if (const auto* gt = recording::nearest_ground_truth(rec, sink.first.t_ns)) {
      // Ground truth nearest the first frame: "up" of the world seen in the body frame.
      const double gravity_err = dsp::angle_deg(est->mean_accel_m_s2, gt->up_body());
      const double bias_err = (est->gyro_bias_rad_s - gt->gyro_bias_rad_s).norm();
      imu["gravity_error_vs_ground_truth_deg"] = gravity_err;
      imu["gyro_bias_error_vs_ground_truth_rad_s"] = bias_err;
      std::snprintf(
          buf, sizeof buf,
          "ground truth: gravity direction off by %.3f deg, gyro bias off by %.5f rad/s\n",
          gravity_err, bias_err);
      text += buf;
    }
    summary["imu"] = imu;
  }
  // The room: until the tracker's map exists (issue 7), a sparse map triangulated from ORB
  // matches of a few stereo pairs. Pairs are merged only while the IMU says the head is
  // still (same camera pose); otherwise the first pair alone is used.
  if (!sink.kept.empty()) {
    const bool still = est && dsp::is_still(*est);
    const RigCalibration rig = rec.rig();
    dsp::SparseStereo stereo(rig);
    const dsp::SparseMap sparse = dsp::build_sparse_map(stereo, sink.kept, still);
    const PointCloud& map = sparse.points;
    dsp::RoomConfig room_cfg;
    room_cfg.detector.threshold_m = kMapThresholdM;
    room_cfg.max_surfaces = 4;
    // Gravity ("down") in the left camera's frame, from the IMU at rest.
    const Eigen::Matrix3d R_body_cam = rig.cams[0].T_body_cam.linear();
    std::optional<Eigen::Vector3d> down_cam;
    if (est && still) down_cam = R_body_cam.transpose() * (-est->mean_accel_m_s2);
    room_cfg.gravity = down_cam;
    dsp::RoomEstimator estimator(map.size());
    const TimeNs t0 = monotonic_now_ns();
    const dsp::RoomResult room = estimator.estimate(map, room_cfg);
    const double time_ms = static_cast<double>(monotonic_now_ns() - t0) * 1e-6;
    nlohmann::json walls = firmware::to_json(room);
    walls["time_ms"] = time_ms;
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "sparse map: %zu points from %zu stereo pairs; %zu surfaces (%s, %u rounds, "
                  "%.1f ms):\n",
                  room.points, sparse.pairs_used, room.surfaces.size(),
                  down_cam ? "gravity-aligned" : "3-D", room.rounds, time_ms);
    text += buf;
    text += firmware::to_text(room);
    // The floor's own orientation, fitted freely in 3-D on its inliers, against gravity.
    if (down_cam) {
      std::optional<Eigen::Vector3d> up_cam_gt;
      if (const auto* gt = recording::nearest_ground_truth(rec, sink.first.t_ns)) {
        up_cam_gt = R_body_cam.transpose() * gt->up_body();
      }
      if (const auto check =
              dsp::check_floor(map, room, kMapThresholdM, -down_cam->normalized(), up_cam_gt)) {
        nlohmann::json floor = {{"distance_below_camera_m", check->distance_below_viewer_m},
                                {"free_fit_vs_imu_gravity_deg", check->free_fit_vs_up_deg}};
        std::snprintf(buf, sizeof buf,
                      "floor %.3f m below the camera; its inliers' free 3-D fit is %.2f deg from "
                      "IMU gravity",
                      check->distance_below_viewer_m, check->free_fit_vs_up_deg);
        text += buf;
        if (check->free_fit_vs_up2_deg) {
          floor["free_fit_vs_ground_truth_gravity_deg"] = *check->free_fit_vs_up2_deg;
          std::snprintf(buf, sizeof buf, ", %.2f deg from ground-truth gravity",
                        *check->free_fit_vs_up2_deg);
          text += buf;
        }
        text += "\n";
        walls["floor_check"] = floor;
      }
    }
    std::ofstream(fs::path(args.out) / "walls.json") << walls.dump(2) << "\n";
    cloud::write_ply_rgb(fs::path(args.out) / "sparse_map.ply", map,
                         firmware::surface_colours(map, room, kMapThresholdM));
    summary["walls"] = walls;
    // The headset view of the kept pairs. The map's world is the first pair's left camera;
    // without the tracker (issue 9 wires it in) the pose is known only while the IMU says the
    // head is still, so a moving recording shows its first pair alone.
    if (!args.no_view) {
      firmware::HeadsetViewOptions view_options = firmware::view_options(board.display);
      view_options.png_dir = fs::path(args.out) / "view";
      view_options.png_every = args.view_every;
      firmware::HeadsetView view(rig, view_options);
      const SE3d T_world_body = rig.cams[0].T_body_cam.inverse();
      display::HudState hud;
      hud.tracking = still ? "at rest" : "first pair";
      hud.fps = rig.cams[0].rate_hz;
      hud.walls = static_cast<int>(room.model.walls.size());
      for (std::size_t i = 0; i < (still ? sink.kept.size() : 1); ++i) {
        if (!view.show(sink.kept[i], 0, T_world_body, true, &room.model, hud)) {
          throw display::DisplayError("display: " + view.describe() + ": " + view.last_error());
        }
      }
      const firmware::HeadsetViewStats& vs = view.stats();
      summary["view"] = {{"display", view.describe()},
                         {"frames", vs.frames},
                         {"written", vs.written_files}};
      std::snprintf(buf, sizeof buf, "headset view: %llu frames on %s, PNGs in %s/view/\n",
                    static_cast<unsigned long long>(vs.frames), view.describe().c_str(),
                    args.out.c_str());
      text += buf;
    }
  }
  if (!sink.first.left.image.empty()) {
    save_side_by_side(fs::path(args.out) / "first_stereo_pair.png", sink.first);
    summary["outputs"] = {"run_summary.json", "first_stereo_pair.png", "walls.json",
                          "sparse_map.ply"};
    if (summary.contains("view")) summary["outputs"].push_back("view/");
  }
  std::ofstream(fs::path(args.out) / "run_summary.json") << summary.dump(2) << "\n";
  if (args.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << text << "outputs in " << args.out << "/\n";
  }
  return stats.stopped ? kExitInterrupted : kExitOk;
}

}  // namespace

void add_run_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "Run the appliance on a board (live or replay)");
  cmd->add_option("--board", args->board, "Board file, e.g. board/sim.yaml")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "Folder for outputs")->capture_default_str();
  cmd->add_flag("--json", args->json, "Print the summary as JSON on stdout");
  cmd->add_flag("--check", args->check, "Only check the board file and exit");
  cmd->add_flag("--no-view", args->no_view, "Do not draw the headset view");
  cmd->add_option("--view-every", args->view_every, "Write every Nth drawn view as PNG")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  add_replay_flags(*cmd, args->flags);
  cmd->callback([args, &run] { run = [args] { return run_run_command(*args); }; });
}

}  // namespace wallar::cli
