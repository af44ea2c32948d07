// SPDX-License-Identifier: Apache-2.0
/// @file cmd_imu.cpp
/// @brief `wallar imu RECORDING`: attitude and gyro bias from the IMU of a recording (EuRoC
/// layout; mav0/imu0 alone is enough), one CSV row per sample, errors against ground truth.
/// `wallar imu --board FILE`: the same from the board's live IMU driver.
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/eval/output.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/board_devices.hpp"
#include "wallar/firmware/imu_attitude.hpp"
#include "wallar/firmware/live_imu.hpp"

namespace wallar::cli {
namespace {

namespace fs = std::filesystem;

struct ImuArgs {
  std::string recording;
  std::string board;
  double seconds = 10.0;
  std::string out;
  std::string plot_dir;
  bool json = false;
};

constexpr const char* kHeader = "t_ns,qw,qx,qy,qz,gx,gy,gz,bgx,bgy,bgz\n";

void append_row(std::string& csv, const firmware::AttitudeRow& r) {
  char buf[320];
  if (!r.valid) {
    std::snprintf(buf, sizeof buf, "%lld,nan,nan,nan,nan,nan,nan,nan,nan,nan,nan\n",
                  static_cast<long long>(r.t_ns));
  } else {
    const Eigen::Quaterniond& q = r.q_world_imu;
    const Eigen::Vector3d& g = r.gravity_dir_imu;
    const Eigen::Vector3d& b = r.gyro_bias_rad_s;
    std::snprintf(buf, sizeof buf, "%lld,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,%.4e,%.4e,%.4e\n",
                  static_cast<long long>(r.t_ns), q.w(), q.x(), q.y(), q.z(), g.x(), g.y(), g.z(),
                  b.x(), b.y(), b.z());
  }
  csv += buf;
}

constexpr const char* kPlotScript =
    R"(set multiplot layout 2,1 title "Attitude filter on EuRoC V1_01: errors against ground truth"
set grid
set key top right
set xlabel "time [s]"
set ylabel "tilt error [deg]"
plot "imu_attitude.csv" skip 1 using 1:2 with lines lw 1.5 title "tilt (roll+pitch) error"
set ylabel "gyro bias error [mrad/s]"
plot "imu_attitude.csv" skip 1 using 1:3 with lines title "x", "" skip 1 using 1:4 with lines title "y", "" skip 1 using 1:5 with lines title "z", "" skip 1 using 1:6 with lines lw 2 title "norm"
unset multiplot
)";

// Live: the driver's samples go through the filter on the imu thread (here, the main one);
// rows are kept in storage reserved for the whole run, so the sink never allocates.
class FilterSink final : public drivers::ImuSampleSink {
 public:
  FilterSink(const dsp::AttitudeFilterConfig& config, std::size_t max_rows) : filter_(config) {
    rows_.reserve(max_rows);
  }
  void on_imu_sample(const ImuSample& sample) noexcept override {
    if (rows_.size() == rows_.capacity()) {
      ++dropped_;
      return;
    }
    const bool was_initialized = filter_.initialized();
    const bool valid = filter_.update(sample);
    if (valid && !was_initialized) {
      // Just initialised from a still window ending here: the window's samples share its
      // estimate, as run_attitude_filter gives them on a recording.
      const TimeNs window_begin_ns = filter_.initial_estimate().t_begin_ns;
      for (auto it = rows_.rbegin(); it != rows_.rend() && it->t_ns >= window_begin_ns; ++it)
        *it = firmware::attitude_row(filter_, it->t_ns, true);
    }
    rows_.push_back(firmware::attitude_row(filter_, sample.t_ns, valid));
  }
  const std::vector<firmware::AttitudeRow>& rows() const { return rows_; }
  std::size_t dropped() const { return dropped_; }

 private:
  dsp::AttitudeFilter filter_;
  std::vector<firmware::AttitudeRow> rows_;
  std::size_t dropped_ = 0;
};

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop.store(true); }

int run_live_imu(const ImuArgs& a) {
  if (!(a.seconds > 0.0 && a.seconds <= 86400.0)) {
    throw InputError("--seconds: must be in (0, 86400], got " + std::to_string(a.seconds));
  }
  // The IMU's devices by their stable names before it opens (each problem one line naming
  // its board key).
  const firmware::BoardConfig board = firmware::check_sensor_board(
      firmware::load_board(a.board), drivers::DeviceTree(), {"imu"},
      [](const std::string& line) { std::cerr << "wallar: " << line << "\n"; });
  dsp::AttitudeFilterConfig config;
  config.init_window_samples = static_cast<std::size_t>(std::max(20.0, board.imu.rate_hz));
  // Room for the whole run at up to twice the nominal rate (an oscillator runs fast, the
  // ICM-20948 rounds its rate up).
  FilterSink sink(config, static_cast<std::size_t>(2.0 * board.imu.rate_hz * a.seconds) + 64);
  firmware::LiveImu imu(board, sink);
  std::fprintf(stderr, "wallar imu: %s, %.1f s (Ctrl-C stops)\n", imu.description().c_str(),
               a.seconds);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  imu.run(monotonic_now_ns() + s_to_ns(a.seconds), g_stop);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);

  if (!a.out.empty()) {
    std::string csv = kHeader;
    for (const firmware::AttitudeRow& r : sink.rows()) append_row(csv, r);
    eval::write_file_atomically(a.out, csv);
  }
  const drivers::ImuDriver& driver = imu.driver();
  const std::string counters = drivers::format_counters(driver.counters());
  if (a.json) {
    nlohmann::json j = {{"board", a.board},
                        {"imu", imu.description()},
                        {"state", std::string(drivers::to_string(driver.state()))},
                        {"rows", sink.rows().size()},
                        {"rows_dropped", sink.dropped()},
                        {"counters", counters}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("wallar imu: %zu samples (%zu not kept), driver %s; %s\n", sink.rows().size(),
                sink.dropped(), std::string(drivers::to_string(driver.state())).c_str(),
                counters.c_str());
    if (!a.out.empty()) std::printf("  wrote %s\n", a.out.c_str());
  }
  if (g_stop.load()) return kExitInterrupted;
  return sink.rows().empty() ? kExitFailure : kExitOk;
}

int run_imu_command(const ImuArgs& a) {
  if (a.recording.empty() == a.board.empty()) {
    throw InputError("wallar imu: give either a RECORDING or --board FILE");
  }
  if (!a.board.empty()) {
    if (!a.plot_dir.empty()) throw InputError("--plot: needs a recording with ground truth");
    return run_live_imu(a);
  }
  const recording::EurocRecording rec = recording::read_recording_imu(a.recording);
  if (rec.imu.empty()) {
    throw_input_error((rec.mav0 / "imu0" / "data.csv").string(), 0, "holds no IMU samples");
  }
  if (!a.plot_dir.empty() && rec.ground_truth.empty()) {
    throw_input_error(a.recording, 0, "--plot needs ground truth (state_groundtruth_estimate0)");
  }
  if (!a.plot_dir.empty() && !eval::gnuplot_available()) {
    throw std::runtime_error("gnuplot is not installed (tools/setup installs gnuplot-nox)");
  }
  std::string csv;
  if (!a.out.empty()) {
    csv.reserve(rec.imu.size() * 140 + 64);
    csv = kHeader;
  }
  eval::CsvTable errors({"t_s", "tilt_deg", "bias_err_x_mrad_s", "bias_err_y_mrad_s",
                         "bias_err_z_mrad_s", "bias_err_norm_mrad_s"});
  const TimeNs t0_ns = rec.imu.front().t_ns;
  TimeNs next_plot_ns = t0_ns;
  Eigen::Vector3d last_gravity_imu = Eigen::Vector3d::Zero();
  const firmware::AttitudeRun run = firmware::run_attitude_filter(
      rec, firmware::attitude_config_for(rec), [&](const firmware::AttitudeRow& r) {
        if (!a.out.empty()) append_row(csv, r);
        if (r.valid) last_gravity_imu = r.gravity_dir_imu;
        if (r.error && r.t_ns >= next_plot_ns) {  // the figure at 20 Hz is plenty
          next_plot_ns = r.t_ns + 50 * kNsPerMs;
          const Eigen::Vector3d& e = r.error->gyro_bias_error_rad_s;
          // Rounded (ms, 1e-4 deg, 1e-4 mrad/s) so the committed table stays small.
          auto round_to = [](double v, double scale) { return std::round(v * scale) / scale; };
          errors.add(round_to(ns_to_s(r.t_ns - t0_ns), 1e3))
              .add(round_to(r.error->tilt_rad * 180.0 / M_PI, 1e4));
          for (const double b : {e.x(), e.y(), e.z(), e.norm()}) errors.add(round_to(b * 1e3, 1e4));
          errors.end_row();
        }
      });
  if (!a.out.empty()) eval::write_file_atomically(a.out, csv);

  nlohmann::json j = {{"recording", a.recording},
                      {"samples", run.samples},
                      {"valid_rows", run.valid_rows},
                      {"duration_s", run.duration_s},
                      {"still_window",
                       {{"t_begin_ns", run.initial.t_begin_ns},
                        {"t_end_ns", run.initial.t_end_ns},
                        {"gyro_bias_rad_s",
                         {run.initial.gyro_bias_rad_s.x(), run.initial.gyro_bias_rad_s.y(),
                          run.initial.gyro_bias_rad_s.z()}}}},
                      {"accel_updates", run.counters.accel_updates},
                      {"accel_rejected", run.counters.accel_rejected},
                      {"mag_updates", run.counters.mag_updates},
                      {"mag_rejected", run.counters.mag_rejected},
                      {"bad_samples", run.counters.bad_samples},
                      {"gaps", run.counters.gaps}};
  if (rec.cams[0].calib.fx > 0.0 && run.valid_rows > 0) {
    const Eigen::Vector3d g_cam0 = rec.rig().T_cam0_imu().linear() * last_gravity_imu;
    j["final_gravity_dir_cam0"] = {g_cam0.x(), g_cam0.y(), g_cam0.z()};
  }
  if (run.errors) {
    const dsp::AttitudeErrorSummary& e = *run.errors;
    j["ground_truth"] = {{"compared_samples", e.samples},
                         {"tilt_rms_deg", e.tilt_rms_deg},
                         {"tilt_max_deg", e.tilt_max_deg},
                         {"tilt_final_deg", e.tilt_final_deg},
                         {"bias_error_final_rad_s", e.bias_error_final_rad_s},
                         {"bias_error_rms_rad_s", e.bias_error_rms_rad_s},
                         {"bias_error_rms_window_s", e.bias_window_s},
                         {"bias_error_max_rad_s", e.bias_error_max_rad_s}};
  }
  if (!a.plot_dir.empty()) {
    eval::OutputDir dir(a.plot_dir);
    dir.write("imu_attitude.csv", errors.text());
    const auto png = dir.plot("imu_attitude", kPlotScript, 900, 700);
    j["figure"] = png ? png->string() : "";
  }
  if (a.json) {
    std::cout << j.dump(2) << "\n";
    return kExitOk;
  }
  std::printf(
      "wallar imu: %zu samples over %.1f s, %zu with an estimate (still window %.2f s .. %.2f s)\n",
      run.samples, run.duration_s, run.valid_rows, ns_to_s(run.initial.t_begin_ns - t0_ns),
      ns_to_s(run.initial.t_end_ns - t0_ns));
  if (run.errors) {
    const dsp::AttitudeErrorSummary& e = *run.errors;
    std::printf(
        "  vs ground truth (%zu samples): tilt RMS %.3f deg, max %.3f deg; gyro bias error "
        "%.2e rad/s at the end, RMS %.2e over the last %.0f s, max %.2e\n",
        e.samples, e.tilt_rms_deg, e.tilt_max_deg, e.bias_error_final_rad_s, e.bias_error_rms_rad_s,
        e.bias_window_s, e.bias_error_max_rad_s);
  }
  if (!a.out.empty()) std::printf("  wrote %s\n", a.out.c_str());
  return kExitOk;
}

}  // namespace

void add_imu_command(CLI::App& app, std::function<int()>& run) {
  auto a = std::make_shared<ImuArgs>();
  CLI::App* cmd = app.add_subcommand(
      "imu", "Attitude and gyro bias from a recording's IMU (error-state Kalman filter)");
  cmd->add_option("recording", a->recording,
                  "EuRoC-layout recording (ROOT or ROOT/mav0); mav0/imu0 alone is enough");
  cmd->add_option("--board", a->board,
                  "Instead of a recording, run the IMU driver named in this board file (live)")
      ->option_text("FILE");
  cmd->add_option("--seconds", a->seconds, "Live: how long to run (default 10)")->option_text("S");
  cmd->add_option("--out", a->out,
                  "Write t_ns,qw,qx,qy,qz,gx,gy,gz,bgx,bgy,bgz per IMU sample to FILE (q: IMU "
                  "into a z-up world; g: unit gravity in the IMU frame; bg: gyro bias [rad/s]; nan "
                  "before the first still window)")
      ->option_text("FILE");
  cmd->add_option("--plot", a->plot_dir,
                  "Write tilt and bias errors against ground truth (imu_attitude.csv, .gp, .png) "
                  "into DIR (needs gnuplot)")
      ->option_text("DIR");
  cmd->add_flag("--json", a->json, "Print the summary as JSON on stdout");
  cmd->callback([a, &run] { run = [a] { return run_imu_command(*a); }; });
}

}  // namespace wallar::cli
