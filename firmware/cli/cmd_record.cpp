// SPDX-License-Identifier: Apache-2.0
/// @file cmd_record.cpp
/// @brief `wallar record`: write the board's sensor streams as an EuRoC recording.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <thread>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/drivers/recording/rotating_writer.hpp"
#include "wallar/drivers/source/async_recorder.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/board_devices.hpp"
#include "wallar/firmware/live_imu.hpp"
#include "wallar/firmware/live_stereo.hpp"
#include "wallar/firmware/report.hpp"
#include "wallar/firmware/source_runner.hpp"

namespace wallar::cli {
namespace {

struct RecordArgs {
  std::string board;
  std::string from;
  std::string out;
  double duration_s = 0.0;
  double segment_mb = 0.0;  // rotation: a new segment at this size (0: one recording)
  double max_mb = 0.0;      // rotation: the oldest segments deleted above this (0: keep all)
  std::string format;       // "euroc" or "mcap"; "" = mcap when --out ends in .mcap
  std::string compression = "zstd";  // MCAP chunks
  bool json = false;
  ReplayFlags flags;
};

// The recording's writer: one EuRoC folder or MCAP file, or rotating segments when asked.
std::unique_ptr<recording::RecordingWriter> make_writer(const RecordArgs& args,
                                                        const RigCalibration& rig) {
  const bool mcap = args.format == "mcap" ||
                    (args.format.empty() && std::filesystem::path(args.out).extension() == ".mcap");
  const bool rotate = args.segment_mb > 0.0 || args.max_mb > 0.0;
  if (!rotate) {
    if (mcap) {
      recording::McapRecordingOptions o;
      o.compression = recording::mcap::parse_compression(args.compression, "--compression");
      return std::make_unique<recording::McapRecordingWriter>(args.out, rig, o);
    }
    std::error_code ec;
    if (std::filesystem::exists(std::filesystem::path(args.out) / "mav0", ec)) {
      throw_input_error(args.out, 0, "already holds a recording (mav0/); refusing to overwrite it");
    }
    return std::make_unique<recording::EurocWriter>(args.out, rig);
  }
  recording::RotationOptions o =
      recording::rotation_from_mib(args.segment_mb, args.max_mb, "wallar record");
  if (mcap) {
    if (std::filesystem::path(args.out).extension() == ".mcap") {
      throw InputError(
          "wallar record: --segment-mb writes a folder of segments (OUT/000001.mcap, "
          "...): give --out a folder and --format mcap");
    }
    o.format = recording::RotationOptions::Format::kMcap;
    o.mcap.compression = recording::mcap::parse_compression(args.compression, "--compression");
  }
  return std::make_unique<recording::RotatingWriter>(args.out, rig, o);
}

// The rotation's figures, when the recording rotates.
void add_rotation(const recording::RecordingWriter& w, nlohmann::json& report, std::string& text) {
  const auto* r = dynamic_cast<const recording::RotatingWriter*>(&w);
  if (r == nullptr) return;
  const recording::RotationCounters& c = r->counters();
  report["rotation"] = firmware::to_json(*r);
  text += "  rotation: " + std::to_string(c.segments_started) + " segments, " +
          std::to_string(c.segments_deleted) + " oldest deleted under the cap (" +
          std::to_string(c.bytes_deleted) + " bytes), kept from " +
          r->segments().front().filename().string() + "\n";
}

std::string recorder_text(const source::RecorderCounters& c,
                          const source::AsyncRecorderOptions& o) {
  return "  recorder: dropped " + std::to_string(c.imu_dropped) + " IMU samples, " +
         std::to_string(c.frames_dropped) + " frames; high water IMU " +
         std::to_string(c.imu_high_water) + "/" + std::to_string(o.imu_capacity) + ", frames " +
         std::to_string(c.frame_high_water) + "/" + std::to_string(o.frame_capacity) +
         "; write errors " + std::to_string(c.write_errors) + "\n";
}

// kExitOk when the recording holds everything the sources delivered; else one line on stderr
// naming what is missing, and kExitFailure.
int recorder_exit_code(const source::RecorderCounters& c) {
  if (c.lost() == 0 && c.error.empty()) return kExitOk;
  std::string line = "wallar: the recording is incomplete:";
  if (c.imu_dropped + c.frames_dropped > 0) {
    line += " dropped " + std::to_string(c.imu_dropped) + " IMU samples and " +
            std::to_string(c.frames_dropped) + " camera frames (the writer fell behind)";
  }
  if (!c.error.empty()) {
    if (c.imu_dropped + c.frames_dropped > 0) line += ";";
    line += " " + std::to_string(c.write_errors) + " samples and frames not written: " + c.error;
  }
  std::cerr << line << "\n";
  return kExitFailure;
}

// The rig written to the recording's sensor.yaml files: the board's calibration when it names
// one, else the cameras' sizes and rates only (intrinsics unknown: calibrate afterwards).
RigCalibration live_rig(const firmware::BoardConfig& board) {
  if (board.calibration) return recording::read_rig_calibration(*board.calibration);
  RigCalibration rig;
  for (int i = 0; i < 2; ++i) {
    CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    c.name = "cam" + std::to_string(i);
    c.width_px = board.cameras[i].width_px;
    c.height_px = board.cameras[i].height_px;
    c.rate_hz = board.cameras[i].fps;
    c.distortion = {0.0, 0.0, 0.0, 0.0};
  }
  rig.imu.rate_hz = board.imu.rate_hz;
  return rig;
}

int run_live_record(const RecordArgs& args, const firmware::BoardConfig& board_in) {
  // The devices by their stable names and the camera modes against a calibration the board
  // names, before anything opens: each problem one line naming its board key.
  const firmware::BoardConfig board = firmware::check_sensor_board(
      board_in, drivers::DeviceTree(), {"cameras", "imu"},
      [](const std::string& line) { std::cerr << "wallar: " << line << "\n"; });
  const RigCalibration rig = live_rig(board);
  // Open the devices before creating the recording, so a missing camera leaves nothing behind;
  // the sources are handed a forwarder that reaches the recorder once it exists (before any
  // sample flows: run() has not started).
  struct Forward final : source::SensorSink, drivers::ImuSampleSink {
    source::AsyncRecorder* to = nullptr;
    void on_imu(const ImuSample& s) override { to->on_imu(s); }
    void on_imu_sample(const ImuSample& s) noexcept override { to->on_imu_sample(s); }
    void on_stereo(const StereoFrame& f) override { to->on_stereo(f); }
    void on_unpaired(int cam, const CameraFrame& f) override { to->on_unpaired(cam, f); }
  };
  Forward forward;
  firmware::LiveStereo cameras(board, forward);
  std::unique_ptr<firmware::LiveImu> imu;
  if (board.imu.driver != "none") imu = std::make_unique<firmware::LiveImu>(board, forward);
  const std::unique_ptr<recording::RecordingWriter> writer = make_writer(args, rig);
  // The bounded writer thread: the capture and IMU threads never wait for the disk; frames are
  // copied out of the V4L2 buffers at once (slots sized for the board's cameras).
  source::AsyncRecorderOptions recorder_options;
  for (std::size_t i = 0; i < 2; ++i) {
    recorder_options.width_px[i] = board.cameras[i].width_px;
    recorder_options.height_px[i] = board.cameras[i].height_px;
  }
  source::AsyncRecorder recorder(*writer, recorder_options);
  forward.to = &recorder;
  std::cerr << "wallar: recording " << cameras.description()
            << (imu ? "; " + imu->description() : std::string("; no IMU")) << " to " << args.out
            << "\n";

  const TimeNs until_ns = args.duration_s > 0.0 ? monotonic_now_ns() + s_to_ns(args.duration_s)
                                                : std::numeric_limits<TimeNs>::max();
  std::atomic<bool> stop{false};
  std::thread imu_thread;
  std::exception_ptr imu_error;
  if (imu) {
    imu_thread = std::thread([&] {
      try {
        imu->run(until_ns, stop);
      } catch (...) {
        imu_error = std::current_exception();
        stop.store(true);
      }
    });
  }
  // Stops on SIGINT/SIGTERM (stop_requested), the time limit, or a failure of either thread.
  std::thread watch([&] {
    while (!stop.load() && !stop_requested().load() && monotonic_now_ns() < until_ns)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    stop.store(true);
  });
  std::exception_ptr capture_error;
  try {
    cameras.run(until_ns, stop);
  } catch (...) {
    capture_error = std::current_exception();
  }
  stop.store(true);
  watch.join();
  if (imu_thread.joinable()) imu_thread.join();
  const source::RecorderCounters rc = recorder.close();  // drains, fsyncs, joins
  if (capture_error) std::rethrow_exception(capture_error);
  if (imu_error) std::rethrow_exception(imu_error);

  const drivers::StereoCapture& cap = cameras.capture();
  nlohmann::json cams = nlohmann::json::array();
  for (int i = 0; i < 2; ++i) {
    const drivers::CameraCounters& c = cap.camera(i).counters();
    cams.push_back({{"device", cap.camera(i).config().device},
                    {"frames", c.frames},
                    {"dropped", c.dropped},
                    {"corrupt", c.corrupt},
                    {"stream_restarts", c.stream_restarts},
                    {"reopens", c.reopens},
                    {"usb_resets", c.usb_resets},
                    {"counters", drivers::format_counters(c)}});
  }
  nlohmann::json report{{"out", args.out},
                        {"imu_rows", rc.imu_written},
                        {"cam_rows", rc.frames_written},
                        {"pairs", cap.pairing().pairs},
                        {"unpaired", {cap.pairing().unpaired[0], cap.pairing().unpaired[1]}},
                        {"cameras", cams},
                        {"recorder", firmware::to_json(rc, recorder_options)}};
  // The IMU driver's counters: what the bus delivered, against the rows that were written.
  std::string imu_counters;
  if (imu) {
    const drivers::ImuCounters& c = imu->driver().counters();
    imu_counters = drivers::format_counters(c);
    report["imu"] = {{"samples", c.samples}, {"counters", imu_counters}};
  }
  std::string rotation_text;
  add_rotation(*writer, report, rotation_text);
  if (args.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << "recorded " << rc.imu_written << " IMU rows, " << rc.frames_written[0] << " + "
              << rc.frames_written[1] << " frames (" << cap.pairing().pairs << " pairs) to "
              << args.out << "\n";
    for (int i = 0; i < 2; ++i)
      std::cout << "  " << cap.camera(i).config().name << ": "
                << drivers::format_counters(cap.camera(i).counters()) << "\n";
    if (imu) std::cout << "  imu: " << imu_counters << "\n";
    std::cout << recorder_text(rc, recorder_options) << rotation_text;
  }
  return recorder_exit_code(rc);
}

int run_record_command(const RecordArgs& args) {
  const firmware::BoardConfig board = firmware::load_board(args.board);
  std::filesystem::path source_path = args.from;
  source::ReplayOptions options;
  if (source_path.empty()) {
    if (board.source != firmware::BoardConfig::Source::kReplay) return run_live_record(args, board);
    source_path = board.replay.recording;
    options.rate = board.replay.rate;
    options.start_offset_ns = s_to_ns(board.replay.start_offset_s);
    options.skip = board.replay.skip;
  }
  options = args.flags.apply(options);
  const recording::EurocRecording rec = read_recording_reporting(source_path);
  const std::unique_ptr<recording::RecordingWriter> writer = make_writer(args, rec.rig());
  // The same writer thread as live recording; replay can wait for room, so nothing is dropped,
  // and its images are heap copies already (nothing to give back early): kept by reference.
  source::AsyncRecorderOptions recorder_options;
  recorder_options.copy_frames = false;
  recorder_options.wait_when_full = true;
  source::AsyncRecorder recorder(*writer, recorder_options);
  const source::ReplayStats stats =
      firmware::run_replay(rec, options, recorder, stop_requested(), s_to_ns(args.duration_s));
  const source::RecorderCounters rc = recorder.close();
  nlohmann::json report{{"out", args.out},
                        {"imu_rows", rc.imu_written},
                        {"cam_rows", rc.frames_written},
                        {"replay", firmware::to_json(stats)},
                        {"recorder", firmware::to_json(rc, recorder_options)}};
  std::string rotation_text;
  add_rotation(*writer, report, rotation_text);
  if (args.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << "recorded " << rc.imu_written << " IMU rows, " << rc.frames_written[0] << " + "
              << rc.frames_written[1] << " frames to " << args.out << "\n"
              << firmware::to_text(stats) << recorder_text(rc, recorder_options) << rotation_text;
  }
  return recorder_exit_code(rc);
}

}  // namespace

void add_record_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<RecordArgs>();
  CLI::App* cmd =
      app.add_subcommand("record", "Record the sensor streams (EuRoC folder, or one MCAP file)");
  cmd->add_option("--board", args->board, "Board file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "Folder (EuRoC) or file (MCAP) to write the recording to")
      ->required();
  cmd->add_option("--format", args->format,
                  "euroc or mcap (default: mcap when --out ends in .mcap, else euroc)")
      ->check(CLI::IsMember({"euroc", "mcap"}));
  cmd->add_option("--compression", args->compression, "MCAP chunk compression: zstd, lz4 or none")
      ->capture_default_str()
      ->check(CLI::IsMember({"zstd", "lz4", "none"}));
  cmd->add_option("--from", args->from,
                  "Record from this recording (EuRoC folder or .mcap) instead of live sensors")
      ->check(CLI::ExistingPath);
  cmd->add_option("--duration-s", args->duration_s, "Stop after this many seconds (0 = no limit)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--segment-mb", args->segment_mb,
                  "Rotate: write OUT/000001, OUT/000002, ... each a whole EuRoC recording (or "
                  "OUT/000001.mcap, ... with --format mcap), a new one begun at this size in MiB")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-mb", args->max_mb,
                  "With --segment-mb: delete the oldest segments while all hold more than this "
                  "(MiB), so a long recording keeps the latest that fits")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--json", args->json, "Print the report as JSON on stdout");
  add_replay_flags(*cmd, args->flags);
  cmd->callback([args, &run] { run = [args] { return run_record_command(*args); }; });
}

}  // namespace wallar::cli
