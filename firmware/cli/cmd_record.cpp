// SPDX-License-Identifier: Apache-2.0
/// @file cmd_record.cpp
/// @brief `wallar record`: write the board's sensor streams as an EuRoC recording.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <limits>
#include <mutex>
#include <thread>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/drivers/source/recorder_sink.hpp"
#include "wallar/firmware/board.hpp"
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
  bool json = false;
  ReplayFlags flags;
};

// Live sources call from two threads (capture, imu); the writer wants one at a time. Recording
// is not on the fixed-rate path, so a mutex will do until the bounded writer thread (issue 9).
class SerialisedSink final : public source::SensorSink, public drivers::ImuSampleSink {
 public:
  explicit SerialisedSink(source::SensorSink& inner) : inner_(inner) {}
  void on_imu(const ImuSample& s) override {
    std::lock_guard lock(mutex_);
    inner_.on_imu(s);
  }
  void on_imu_sample(const ImuSample& s) noexcept override {
    try {
      on_imu(s);
    } catch (const std::exception& e) {
      std::lock_guard lock(mutex_);
      if (error_.empty()) error_ = e.what();
    }
  }
  void on_stereo(const StereoFrame& f) override {
    std::lock_guard lock(mutex_);
    inner_.on_stereo(f);
  }
  void on_unpaired(int cam, const CameraFrame& f) override {
    std::lock_guard lock(mutex_);
    inner_.on_unpaired(cam, f);
  }
  std::string error() {
    std::lock_guard lock(mutex_);
    return error_;
  }

 private:
  std::mutex mutex_;
  source::SensorSink& inner_;
  std::string error_;
};

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

int run_live_record(const RecordArgs& args, const firmware::BoardConfig& board) {
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::path(args.out) / "mav0", ec))
    throw_input_error(args.out, 0, "already holds a recording (mav0/); refusing to overwrite it");
  const RigCalibration rig = live_rig(board);
  // Open the devices before creating the recording, so a missing camera leaves nothing behind.
  struct Forward final : source::SensorSink {
    source::SensorSink* to = nullptr;
    void on_imu(const ImuSample& s) override { to->on_imu(s); }
    void on_stereo(const StereoFrame& f) override { to->on_stereo(f); }
    void on_unpaired(int cam, const CameraFrame& f) override { to->on_unpaired(cam, f); }
  };
  Forward forward;
  SerialisedSink serial(forward);
  firmware::LiveStereo cameras(board, serial);
  std::unique_ptr<firmware::LiveImu> imu;
  if (board.imu.driver != "none") imu = std::make_unique<firmware::LiveImu>(board, serial);
  recording::EurocWriter writer(args.out, rig);
  source::RecorderSink recorder(writer);
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
  writer.close();
  if (capture_error) std::rethrow_exception(capture_error);
  if (imu_error) std::rethrow_exception(imu_error);
  if (const std::string e = serial.error(); !e.empty()) throw InputError(e);

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
  const nlohmann::json report{{"out", args.out},
                              {"imu_rows", writer.imu_written()},
                              {"cam_rows", {writer.frames_written(0), writer.frames_written(1)}},
                              {"pairs", cap.pairing().pairs},
                              {"unpaired", {cap.pairing().unpaired[0], cap.pairing().unpaired[1]}},
                              {"cameras", cams}};
  if (args.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << "recorded " << writer.imu_written() << " IMU rows, " << writer.frames_written(0)
              << " + " << writer.frames_written(1) << " frames (" << cap.pairing().pairs
              << " pairs) to " << args.out << "\n";
    for (int i = 0; i < 2; ++i)
      std::cout << "  " << cap.camera(i).config().name << ": "
                << drivers::format_counters(cap.camera(i).counters()) << "\n";
  }
  return kExitOk;
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
  const recording::EurocRecording rec = recording::read_euroc(source_path);

  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::path(args.out) / "mav0", ec)) {
    throw_input_error(args.out, 0, "already holds a recording (mav0/); refusing to overwrite it");
  }
  recording::EurocWriter writer(args.out, rec.rig());
  source::RecorderSink sink(writer);
  const source::ReplayStats stats =
      firmware::run_replay(rec, options, sink, stop_requested(), s_to_ns(args.duration_s));
  writer.close();
  if (args.json) {
    std::cout << nlohmann::json{{"out", args.out},
                                {"imu_rows", writer.imu_written()},
                                {"cam_rows", {writer.frames_written(0), writer.frames_written(1)}},
                                {"replay", firmware::to_json(stats)}}
                     .dump(2)
              << "\n";
  } else {
    std::cout << "recorded " << writer.imu_written() << " IMU rows, " << writer.frames_written(0)
              << " + " << writer.frames_written(1) << " frames to " << args.out << "\n"
              << firmware::to_text(stats);
  }
  return kExitOk;
}

}  // namespace

void add_record_command(CLI::App& app, std::function<int()>& run) {
  auto args = std::make_shared<RecordArgs>();
  CLI::App* cmd = app.add_subcommand("record", "Record the sensor streams in the EuRoC layout");
  cmd->add_option("--board", args->board, "Board file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "Folder to write the recording to")->required();
  cmd->add_option("--from", args->from, "Record from this recording instead of live sensors")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--duration-s", args->duration_s, "Stop after this many seconds (0 = no limit)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--json", args->json, "Print the report as JSON on stdout");
  add_replay_flags(*cmd, args->flags);
  cmd->callback([args, &run] { run = [args] { return run_record_command(*args); }; });
}

}  // namespace wallar::cli
