// SPDX-License-Identifier: Apache-2.0
/// @file cmd_run.cpp
/// @brief `wallar run --board FILE`: the appliance on a board (firmware/appliance.hpp): every
/// module on its thread from the board file until the replay ends, SIGINT/SIGTERM, the exit
/// input or --duration; SIGUSR1 prints the stats table meanwhile. Prints the wall model and a
/// summary (--stats: the table of threads and stages) and writes them under --out, in the
/// first body pose's world (as `wallar track` writes its files).
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/camera/v4l2_system.hpp"
#include "wallar/drivers/cloud/cloud_io.hpp"
#include "wallar/drivers/devices/device_names.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/drivers/recording/rotating_writer.hpp"
#include "wallar/drivers/recording/tum_trajectory.hpp"
#include "wallar/drivers/source/async_recorder.hpp"
#include "wallar/firmware/appliance.hpp"
#include "wallar/firmware/appliance/stats.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/board_devices.hpp"
#include "wallar/firmware/device_measurement.hpp"
#include "wallar/firmware/hil/replay_plan.hpp"
#include "wallar/firmware/offline.hpp"
#include "wallar/firmware/report.hpp"

namespace wallar::cli {
namespace {
namespace fs = std::filesystem;

struct RunArgs {
  std::string board;
  std::string out = "out";
  bool json = false;
  bool check = false;
  std::string root;  // --check: a device tree under this folder instead of this machine's
  bool stats = false;
  bool no_view = false;
  int view_every = 0;  // no PNGs unless asked: on a headset they fill and wear the SD card
  bool deterministic = false;
  bool no_rt = false;
  int loops = -1;  // -1: the board's replay.loop
  double duration_s = 0.0;
  std::vector<std::string> faults;
  std::string method = score_method_name(dsp::RoomConfig{}.detector.method);
  std::uint64_t seed = 1;
  std::string keys;
  std::string live;    // [ADDRESS:]PORT
  std::string record;  // FILE.mcap, or a folder of segments
  double record_segment_mb = 0.0;
  double record_max_mb = 0.0;
  bool no_live = false;
  std::string client_socket;  // PATH
  bool no_client = false;
  ReplayFlags flags;
};

// A server of the run (the live server, the client API): off (null, its endpoint empty), or
// its endpoint under `key` and its counters at the end.
nlohmann::json server_json(const char* key, const std::string& endpoint,
                           const std::vector<std::pair<const char*, std::uint64_t>>& counters) {
  if (endpoint.empty()) return nullptr;
  nlohmann::json j = {{key, endpoint}};
  for (const auto& [name, value] : counters) j[name] = value;
  return j;
}

nlohmann::json to_json(const firmware::ApplianceReport& r, const firmware::RunOutputs& out) {
  const nlohmann::json threads = firmware::to_json(r.threads);
  const nlohmann::json stages = firmware::to_json(r.stages);
  nlohmann::json devices = nlohmann::json::object();
  for (const auto& [name, counters] : r.devices) devices[name] = counters;
  const firmware::DegradedCounters& d = r.degraded;
  const firmware::TrackingCounters& c = r.tracking;
  nlohmann::json j = {
      {"source", r.source},
      {"mode", firmware::to_string(r.mode)},
      {"display", r.display},
      {"stop_reason", r.stop_reason},
      {"wall_time_s", ns_to_s(r.wall_time_ns)},
      {"loops", r.loops_played},
      {"replay", firmware::to_json(r.replay)},
      {"imu", {{"present", r.imu}, {"samples", r.imu_samples}, {"dropped", r.imu_dropped}}},
      {"frames",
       {{"in", r.frames_in}, {"overwritten", r.frames_overwritten}, {"tracked", r.frames_tracked}}},
      {"tracking",
       {{"frames", c.frames},
        {"keyframes", c.keyframes},
        {"keyframes_deferred", c.keyframes_deferred},
        {"new_segments", c.new_segments},
        {"map_full_keyframes", c.map_full_keyframes},
        {"culled_keyframes", c.culled_keyframes},
        {"stale_updates", c.stale_updates},
        {"lost_frames", c.lost_frames},
        {"rejected_frames", c.rejected_frames},
        {"relocalisations", c.relocalisations},
        {"local_adjustments", c.local_adjustments},
        {"global_adjustments", c.global_adjustments}}},
      {"map", {{"points", r.map_points}, {"keyframes", r.map_keyframes}}},
      {"reconstructions", r.reconstructions},
      {"degraded",
       {{"camera_lost", d.camera_lost},
        {"camera_recovered", d.camera_recovered},
        {"imu_lost", d.imu_lost},
        {"imu_recovered", d.imu_recovered},
        {"imu_only_poses", d.imu_only_poses},
        {"faults_injected", d.faults_injected},
        {"resets", d.resets}}},
      {"events", r.events},
      {"devices", devices},
      {"view",
       {{"posted", r.view.posted},
        {"drawn", r.view.view.frames},
        {"on_screen", r.view.view.on_screen},
        {"skipped", r.view.skipped},
        {"frozen", r.view.frozen},
        {"written", r.view.view.written},
        {"losses", r.view.losses}}},
      {"threads", threads},
      {"stages", stages},
      {"live", server_json("url", r.live_url, r.live)},
      {"client", server_json("socket", r.client_socket, r.client)},
      {"memory_locked", r.memory_locked},
      {"max_rss_kb", r.max_rss_kb}};
  if (out.room) {
    j["walls"] = firmware::to_json(*out.room);
    j["walls"]["mode"] = firmware::to_string(r.room_gravity);
    j["walls"]["frame"] = "world: the first body pose";
  }
  return j;
}

// `--check`: the board file, its calibration and every device it names, found on this machine
// (firmware/board_devices.hpp); then, when all is there, the cameras and the IMU run for a few
// seconds through the appliance's own modules (firmware/device_measurement.hpp): the pair's
// pairing rate and skew, the IMU's delivered rate. What was found goes to stdout, each
// problem to stderr as one line naming the key and the device; exit 2 when the board
// contradicts itself or its calibration, 1 when a device is missing or falls short.
// With --root the devices are looked up in a tree copied from a board (or a test's fake):
// its files answer no ioctl, so the cameras are not asked for their modes, nothing is
// measured, and GPIO chips are described by the tree's sysfs.
int run_check(const RunArgs& args, const firmware::BoardConfig& board) {
  const bool own = args.root.empty();
  const drivers::DeviceTree tree =
      own ? drivers::DeviceTree()
          : drivers::DeviceTree(args.root, drivers::gpio_chip_info_in(args.root));
  firmware::BoardCheck check =
      firmware::check_board(board, tree, own ? &drivers::linux_v4l2_system() : nullptr);
  const bool live = board.source == firmware::BoardConfig::Source::kLive;
  std::vector<std::pair<std::string, std::string>> counters;  // the measured devices
  if (!own && live) {
    check.found.push_back(
        {"camera modes", "not asked (devices under " + args.root + ", not this machine's)"});
  }
  if (own && live && check.ok()) {
    // The devices as the product opens them (links kept, chips by path), as the check found
    // them.
    const firmware::DeviceMeasurement m =
        firmware::measure_devices(check.resolved, drivers::linux_v4l2_system(),
                                  [](const std::string& line) { std::cerr << line << "\n"; });
    char buf[160];
    if (m.sync) {
      std::snprintf(buf, sizeof buf, "%.1f %% of %llu frames paired, skew mean %.1f max %.1f ms",
                    m.sync->paired_percent, static_cast<unsigned long long>(m.sync->frames),
                    m.sync->mean_skew_ms, m.sync->max_skew_ms);
      check.found.push_back({"stereo sync (measured)", buf});
    }
    if (m.imu_rate_hz) {
      std::snprintf(buf, sizeof buf, "%.1f Hz delivered (runs at %.1f Hz)", *m.imu_rate_hz,
                    m.imu_nominal_hz);
      check.found.push_back({"imu rate (measured)", buf});
    }
    for (const std::string& p : m.problems) check.problems.push_back({p, false});
    counters = m.counters;
  }
  std::cout << "board " << board.name << " (" << args.board << (own ? "" : " in " + args.root)
            << "):\n";
  std::size_t width = 0;
  for (const auto& f : check.found) width = std::max(width, f.key.size());
  for (const auto& f : check.found) {
    std::cout << "  " << f.key << std::string(width + 2 - f.key.size(), ' ') << f.found << "\n";
  }
  // The drivers' counters, as `wallar record` prints them.
  for (const auto& [device, text] : counters) std::cout << "  " << device << ": " << text << "\n";
  for (const auto& p : check.problems) {
    std::cerr << "wallar: " << args.board << ": " << p.line << "\n";
  }
  if (check.ok()) {
    std::cout << "board " << board.name << ": ok\n";
    return kExitOk;
  }
  return check.any_bad_input() ? kExitBadInput : kExitFailure;
}

// The rig the board runs with: its replay's, or its calibration file's (checked again, with
// the devices, when the appliance starts).
RigCalibration board_rig(const firmware::BoardConfig& board) {
  if (board.source == firmware::BoardConfig::Source::kReplay) {
    return recording::read_recording(board.replay.recording).rig();
  }
  if (!board.calibration) {
    throw InputError(board.file.string() + ": a live board needs calibration: to track");
  }
  return recording::read_rig_calibration(*board.calibration);
}

int run_run_command(const RunArgs& args) {
  if (!args.root.empty() && !args.check) throw InputError("--root: only with --check");
  firmware::BoardConfig board = firmware::load_board(args.board);
  if (!args.live.empty()) {
    if (!board.live) board.live.emplace();
    firmware::set_live_endpoint(*board.live, args.live, "--live");
  }
  if (args.no_live) board.live.reset();
  if (!args.client_socket.empty()) {
    if (!board.client) board.client.emplace();
    if (args.client_socket.size() > 107) {
      throw InputError("--client-socket: '" + args.client_socket +
                       "': a UNIX socket's path is at most 107 bytes");
    }
    board.client->socket = args.client_socket;
  }
  if (args.no_client) board.client.reset();
  if (args.check) return run_check(args, board);
  firmware::ApplianceOptions options;
  source::ReplayOptions replay;
  replay.rate = board.replay.rate;
  replay.start_offset_ns = s_to_ns(board.replay.start_offset_s);
  replay.skip = board.replay.skip;
  options.replay = args.flags.apply(replay);
  options.max_duration_ns = s_to_ns(args.duration_s);
  options.mode =
      args.deterministic ? firmware::ApplianceMode::kLockStep : firmware::ApplianceMode::kRealTime;
  options.view = !args.no_view;
  if (args.view_every > 0) options.png_dir = fs::path(args.out) / "view";
  options.png_every = args.view_every;
  // Test tooling between the replay and the pipeline (firmware/hil), only when asked for.
  std::vector<firmware::hil::FaultSpec> faults;
  for (const std::string& f : args.faults) faults.push_back(firmware::hil::parse_fault(f));
  options.before_frame = firmware::hil::tracking_hangs(faults);
  options.before_draw = firmware::hil::render_hangs(faults);
  const int loops = args.loops >= 0 ? args.loops : static_cast<int>(board.replay.loops);
  if (loops != 1 || !faults.empty()) {
    options.replay_plan = firmware::hil::replay_plan(loops, std::move(faults));
  }
  options.wall_method = score_method_named(args.method);
  options.seed = args.seed;
  options.realtime = !args.no_rt;
  options.input_keys = args.keys;

  std::error_code ec;
  fs::create_directories(args.out, ec);
  if (ec) throw_input_error(args.out, 0, "cannot create output folder: " + ec.message());

  // --record FILE.mcap: the sensor streams as the source delivers them (the recorder's rings:
  // a full ring drops and counts, never waits), then the run's outputs.
  std::unique_ptr<recording::RecordingWriter> record_writer;
  std::unique_ptr<source::AsyncRecorder> recorder;
  source::AsyncRecorderOptions record_options;
  const bool rotate = args.record_segment_mb > 0.0 || args.record_max_mb > 0.0;
  if (rotate && args.record.empty()) throw InputError("--record-segment-mb: needs --record");
  if (!args.record.empty()) {
    const bool mcap_name = fs::path(args.record).extension() == ".mcap";
    if (!rotate && !mcap_name) {
      throw InputError("--record: '" + args.record +
                       "' is not an .mcap file (`wallar record` writes EuRoC folders)");
    }
    if (rotate && mcap_name) {
      throw InputError("--record-segment-mb writes a folder of segments (" + args.record +
                       "/000001.mcap, ...): name the folder without .mcap");
    }
    const RigCalibration rig = board_rig(board);
    if (rotate) {
      recording::RotationOptions o = recording::rotation_from_mib(
          args.record_segment_mb, args.record_max_mb, "wallar run --record");
      o.format = recording::RotationOptions::Format::kMcap;
      record_writer = std::make_unique<recording::RotatingWriter>(args.record, rig, o);
    } else {
      record_writer = std::make_unique<recording::McapRecordingWriter>(args.record, rig);
    }
    for (std::size_t i = 0; i < 2; ++i) {
      record_options.width_px[i] = rig.cams[i].width_px;
      record_options.height_px[i] = rig.cams[i].height_px;
    }
    record_options.close_writer = false;  // the outputs follow the streams
    recorder = std::make_unique<source::AsyncRecorder>(*record_writer, record_options);
    options.record = recorder.get();
  }

  const firmware::ApplianceReport report =
      firmware::run_appliance(board, options, stop_requested(), &stats_requested());

  // Outputs in the first body pose's world: the wall model, the map coloured by surface, the
  // trajectory (every frame tracking took), the summary.
  const firmware::RunOutputs out = firmware::outputs_in_body_world(report);
  nlohmann::json summary = to_json(report, out);
  summary["board"] = board.name;
  nlohmann::json outputs = {"run_summary.json", "trajectory.tum"};
  std::ofstream(fs::path(args.out) / "trajectory.tum") << recording::format_tum(out.poses);
  if (out.room) {
    std::ofstream(fs::path(args.out) / "walls.json") << summary["walls"].dump(2) << "\n";
    outputs.push_back("walls.json");
    if (report.map) {
      cloud::write_ply_rgb(fs::path(args.out) / "map.ply", out.map,
                           firmware::surface_colours(out.map, *out.room, options.wall_threshold_m));
      outputs.push_back("map.ply");
    }
  }
  if (report.view.view.written > 0) outputs.push_back("view/");
  if (recorder) {
    const source::RecorderCounters c = recorder->close();
    // The outputs go into the file, or the last segment.
    auto* rotating = dynamic_cast<recording::RotatingWriter*>(record_writer.get());
    recording::McapRecordingWriter* outputs_to =
        rotating != nullptr ? rotating->current_mcap()
                            : static_cast<recording::McapRecordingWriter*>(record_writer.get());
    if (c.error.empty()) firmware::write_outputs_mcap(*outputs_to, out);
    record_writer->close();
    summary["record"] = firmware::to_json(c, record_options);
    summary["record"]["file"] = args.record;
    if (rotating != nullptr) summary["record"]["rotation"] = firmware::to_json(*rotating);
    summary["record"]["imu_rows"] = c.imu_written;
    summary["record"]["cam_rows"] = c.frames_written;
    summary["record"]["outputs"] = c.error.empty();
  }
  summary["outputs"] = outputs;
  std::ofstream(fs::path(args.out) / "run_summary.json") << summary.dump(2) << "\n";

  if (args.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::printf("wallar run: board %s, %s\n", board.name.c_str(), report.source.c_str());
    std::printf(
        "  %llu frames tracked of %llu (%llu overwritten), %llu IMU samples (%llu "
        "dropped), map %zu points in %zu key-frames, %s after %.2f s\n",
        static_cast<unsigned long long>(report.frames_tracked),
        static_cast<unsigned long long>(report.frames_in),
        static_cast<unsigned long long>(report.frames_overwritten),
        static_cast<unsigned long long>(report.imu_samples),
        static_cast<unsigned long long>(report.imu_dropped), report.map_points,
        report.map_keyframes, report.stop_reason.c_str(), ns_to_s(report.wall_time_ns));
    for (const std::string& e : report.events) std::printf("  event: %s\n", e.c_str());
    for (const auto& [name, counters] : report.devices) {
      std::printf("  %s: %s\n", name.c_str(), counters.c_str());
    }
    if (report.view.view.frames > 0) {
      std::printf("  view: %llu drawn, %llu on screen, %llu present failures, %llu reopens\n",
                  static_cast<unsigned long long>(report.view.view.frames),
                  static_cast<unsigned long long>(report.view.view.on_screen),
                  static_cast<unsigned long long>(report.view.view.present_failures),
                  static_cast<unsigned long long>(report.view.reopens));
    }
    if (out.room) {
      std::printf("wall model (%s, %llu reconstructions, world = first body pose):\n",
                  firmware::to_string(report.room_gravity),
                  static_cast<unsigned long long>(report.reconstructions));
      std::cout << firmware::to_text(*out.room);
    } else {
      std::printf("wall model: none (the map has too few points)\n");
    }
    if (args.stats) {
      std::printf("\n%s", firmware::format_stats_table(report.threads, report.stages).c_str());
    }
    std::printf("outputs in %s/\n", args.out.c_str());
  }
  // SIGTERM is the service manager's stop (systemctl stop, shutdown): the appliance did what
  // it was asked, exit 0. SIGINT (a terminal's Ctrl-C) and the exit input give 130.
  if (report.interrupted && stop_signal().load() == SIGTERM) return kExitOk;
  return report.interrupted ? kExitInterrupted : kExitOk;
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
  cmd->add_flag("--check", args->check,
                "Check the board file, its calibration and every device it names (GPIO chips "
                "by label, udev links), then run the cameras and the IMU for a few seconds "
                "(stereo pairing and skew, the IMU's rate), and exit");
  cmd->add_option("--root", args->root,
                  "With --check: look the devices up under this folder (its dev/ and sys/: a "
                  "tree copied from a board) instead of this machine's")
      ->check(CLI::ExistingDirectory);

  cmd->add_flag("--stats", args->stats,
                "Print the table of threads and stages at the end (SIGUSR1: at any time)");
  cmd->add_flag("--no-view", args->no_view, "Do not draw the headset view");
  cmd->add_option("--view-every", args->view_every,
                  "Write every Nth drawn view as PNG under OUT/view (default: none)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--deterministic", args->deterministic,
                "Replay in lock step (no frame dropped, mapping and walls at fixed points): "
                "the same poses and walls on every run");
  cmd->add_flag("--no-rt", args->no_rt, "Do not ask for SCHED_FIFO, affinity or mlockall");
  cmd->add_option("--loop", args->loops,
                  "Replay the recording N times (0: until stopped; default: the board's "
                  "replay.loop, 1)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--duration", args->duration_s, "Stop after this many seconds")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--fault", args->faults,
                  "Inject a fault into the replayed streams (camera-stall@T+D, imu-unplug@T+D, "
                  "corrupt-frame@T), the tracking thread (tracking-hang@T+D) or the render thread "
                  "(render-hang@T+D); seconds from "
                  "the start; repeatable");
  cmd->add_option("--method", args->method,
                  "Wall search score: ransac, msac, bsf (BSF-RANSAC), binomial (B-RANSAC) or "
                  "contrast (BSF on the band's contrast)")
      ->check(CLI::IsMember(kScoreMethodNames))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed of the wall search")->capture_default_str();
  cmd->add_option("--keys", args->keys,
                  "Keyboard for reset (R) and exit (Q, Esc): /dev/input/eventN or name:TEXT");
  cmd->add_option("--live", args->live,
                  "Serve the run live to Foxglove (its WebSocket protocol) on [ADDRESS:]PORT: "
                  "8765 is 127.0.0.1:8765, 0.0.0.0:8765 every network (default: the board's "
                  "live:, or off)");
  cmd->add_option("--record", args->record,
                  "Record the run in one MCAP file: the sensor streams as they come (images, "
                  "IMU), then the run's /pose, /tf, /map and /walls (as `wallar track --mcap`)");
  cmd->add_option("--record-segment-mb", args->record_segment_mb,
                  "With --record DIR: rotate, DIR/000001.mcap, DIR/000002.mcap, ... a new "
                  "segment at this size in MiB (the outputs go into the last one)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--record-max-mb", args->record_max_mb,
                  "With --record-segment-mb: delete the oldest segments while all hold more "
                  "than this (MiB): a long session keeps the latest that fits")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--no-live", args->no_live, "Do not serve live, whatever the board says")
      ->excludes(cmd->get_option("--live"));
  cmd->add_option("--client-socket", args->client_socket,
                  "Serve the client API (libwallar-client: pose, planes) on this UNIX socket "
                  "(default: the board's client:, or off)");
  cmd->add_flag("--no-client", args->no_client,
                "Do not serve the client API, whatever the board says")
      ->excludes(cmd->get_option("--client-socket"));
  add_replay_flags(*cmd, args->flags);
  cmd->callback([args, &run] { run = [args] { return run_run_command(*args); }; });
}

}  // namespace wallar::cli
