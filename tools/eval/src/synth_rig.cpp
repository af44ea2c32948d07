// SPDX-License-Identifier: Apache-2.0
/// @file synth_rig.cpp
/// @brief The synthetic headset recording: head motion, IMU and stereo frames in time order
/// into a EurocWriter, the ground truth and the generator's parameters beside them.
#include "wallar/eval/synth_rig.hpp"

#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>
#include <string>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"

namespace wallar::eval {
namespace fs = std::filesystem;
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
// The IMU starts this long before the first frame and runs this long after the last.
constexpr DurationNs kImuLeadNs = 500 * kNsPerMs;
constexpr DurationNs kImuTailNs = 100 * kNsPerMs;

[[noreturn]] void bad_option(const std::string& option, const std::string& what) {
  throw InputError(option + ": " + what);
}

void check_range(const char* option, double value, double lo, double hi, const char* unit) {
  if (!(value >= lo && value <= hi)) {
    std::ostringstream s;
    s << "must be " << lo << "-" << hi << (unit[0] ? " " : "") << unit << ", got " << value;
    bad_option(option, s.str());
  }
}

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The shortest text that reads back as v ("0.004", not EuRoC's 17 digits), ".0" on integral
// values so YAML readers see a float.
std::string yaml_num(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, r.ptr);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

// A file written row by row inside the .part tree (the tree is renamed when whole).
class RowFile {
 public:
  RowFile(const fs::path& path, std::string_view header) : path_(path) {
    f_ = std::fopen(path.c_str(), "wb");
    if (f_ == nullptr) throw_input_error(path.string(), 0, "cannot create");
    std::setvbuf(f_, nullptr, _IOFBF, 1 << 16);
    write(header);
  }
  ~RowFile() {
    if (f_ != nullptr) std::fclose(f_);
  }
  RowFile(const RowFile&) = delete;
  RowFile& operator=(const RowFile&) = delete;
  void write(std::string_view text) {
    if (std::fwrite(text.data(), 1, text.size(), f_) != text.size()) {
      throw_input_error(path_.string(), 0, "write failed (disk full?)");
    }
  }
  void close() {
    const bool ok = std::fflush(f_) == 0 && ::fsync(::fileno(f_)) == 0;
    const bool closed = std::fclose(f_) == 0;
    f_ = nullptr;
    if (!ok || !closed) throw_input_error(path_.string(), 0, "write failed (disk full?)");
  }

 private:
  fs::path path_;
  std::FILE* f_ = nullptr;
};

void write_text(const fs::path& path, const std::string& text) {
  RowFile f(path, text);
  f.close();
}

std::string matrix_rows_yaml(const Eigen::Matrix4d& m, const char* indent) {
  std::string s;
  for (int r = 0; r < 4; ++r) {
    s += indent;
    s += "- [";
    for (int c = 0; c < 4; ++c) s += yaml_num(m(r, c)) + (c < 3 ? ", " : "]\n");
  }
  return s;
}

// Kalibr's camchain-imucam.yaml: where a camera-IMU calibration carries the time offset.
std::string camchain_yaml(const RigCalibration& rig, double baseline_m, DurationNs offset_ns) {
  std::string s =
      "# Kalibr camchain-imucam form, written by wallar eval synth-rig (exact values)\n";
  for (int i = 0; i < 2; ++i) {
    const CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    const SE3d T_cam_imu = c.T_body_cam.inverse() * rig.imu.T_body_imu;
    s += "cam" + std::to_string(i) + ":\n  T_cam_imu:\n" +
         matrix_rows_yaml(T_cam_imu.matrix(), "  ");
    if (i == 1) {
      // cam1 sits baseline_m along cam0's x with cam0's orientation: exactly this.
      const SE3d T_cam1_cam0(Eigen::Translation3d(-baseline_m, 0.0, 0.0));
      s += "  T_cn_cnm1:\n" + matrix_rows_yaml(T_cam1_cam0.matrix(), "  ");
    }
    s += "  cam_overlaps: [" + std::to_string(1 - i) + "]\n";
    s += "  camera_model: pinhole\n  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]\n";
    s += "  distortion_model: radtan\n";
    s += "  intrinsics: [" + yaml_num(c.fx) + ", " + yaml_num(c.fy) + ", " + yaml_num(c.cx) + ", " +
         yaml_num(c.cy) + "]\n";
    s +=
        "  resolution: [" + std::to_string(c.width_px) + ", " + std::to_string(c.height_px) + "]\n";
    s += "  rostopic: /cam" + std::to_string(i) + "/image_raw\n";
    s += "  timeshift_cam_imu: " + yaml_num(static_cast<double>(offset_ns) * 1e-9) +
         "  # [s] t_imu = t_cam + shift\n";
  }
  return s;
}

}  // namespace

void check_synth_rig_options(const SynthRigOptions& o) {
  check_range("--duration", o.duration_s, 0.05, 3600.0, "s");
  check_range("--camera-rate", o.camera_rate_hz, 1.0, 120.0, "Hz");
  check_range("--imu-rate", o.imu_rate_hz, 200.0, 1000.0, "Hz");
  if (o.imu_rate_hz < o.camera_rate_hz) bad_option("--imu-rate", "must be at least --camera-rate");
  const double period_ms = 1000.0 / o.camera_rate_hz;
  if (o.blur) check_range("--blur", o.exposure_ms, 0.01, period_ms, "ms (the frame period)");
  check_range("--rolling-shutter", o.rolling_shutter_ms, 0.0, period_ms, "ms (the frame period)");
  check_range("--noise", o.noise_sigma, 0.0, 50.0, "gray levels");
  check_range("--time-offset-ms", o.time_offset_ms, -1000.0, 1000.0, "ms");
  check_range("--peak-turn-deg-s", o.peak_turn_deg_s, 30.0, 1500.0, "deg/s");
  check_range("--width", o.width_px, 64, 4096, "px");
  check_range("--height", o.height_px, 48, 4096, "px");
  if (o.focal_px != 0.0) check_range("--focal-px", o.focal_px, 10.0, 20000.0, "px");
  if (o.imu_noise) {
    const ImuCalibration& n = *o.imu_noise;
    for (const double d :
         {n.gyro_noise_density, n.gyro_random_walk, n.accel_noise_density, n.accel_random_walk}) {
      if (!(d >= 0.0 && d < 10.0)) bad_option("--imu-noise-from", "noise densities must be 0-10");
    }
  }
  const std::int64_t frames =
      static_cast<std::int64_t>(std::floor(o.duration_s * o.camera_rate_hz + 1e-6));
  if (frames < 1) bad_option("--duration", "must hold at least one frame at --camera-rate");
}

dsp::HeadsetRig synth_rig_headset(const SynthRigOptions& o) {
  dsp::HeadsetRig rig = dsp::default_headset_rig();
  const double scale = static_cast<double>(o.width_px) / rig.camera.width_px;
  rig.camera.width_px = o.width_px;
  rig.camera.height_px = o.height_px;
  rig.camera.f_px = o.focal_px > 0.0 ? o.focal_px : rig.camera.f_px * scale;
  rig.camera.cx_px = 0.5 * (o.width_px - 1);
  rig.camera.cy_px = 0.5 * (o.height_px - 1);
  if (o.imu_noise) {
    rig.imu.gyro_noise_density = o.imu_noise->gyro_noise_density;
    rig.imu.gyro_random_walk = o.imu_noise->gyro_random_walk;
    rig.imu.accel_noise_density = o.imu_noise->accel_noise_density;
    rig.imu.accel_random_walk = o.imu_noise->accel_random_walk;
  }
  rig.imu.rate_hz = o.imu_rate_hz;
  return rig;
}

nlohmann::json write_synth_rig(const SynthRigOptions& o, const fs::path& out,
                               const std::atomic<bool>& stop) {
  check_synth_rig_options(o);
  std::error_code ec;
  if (fs::exists(out, ec) && !(fs::is_directory(out, ec) && fs::is_empty(out, ec))) {
    throw_input_error(out.string(), 0, "already exists (synth-rig writes a new recording)");
  }
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = cpu_seconds();

  const dsp::SyntheticRoom room = dsp::headset_room(o.seed);
  dsp::HeadMotionConfig mc;
  mc.motion = o.motion;
  mc.seed = o.seed;
  mc.peak_turn_deg_s = o.peak_turn_deg_s;
  mc.duration_s = o.duration_s;
  const dsp::HeadMotionModel model(room, mc);
  const dsp::HeadsetRig rig = synth_rig_headset(o);
  RigCalibration calib = dsp::headset_rig_calibration(rig, o.camera_rate_hz, o.imu_rate_hz);

  dsp::ImagingConfig ic;
  ic.blur = o.blur;
  ic.exposure_s = o.exposure_ms * 1e-3;
  ic.rolling_shutter_s = o.rolling_shutter_ms * 1e-3;
  ic.read_noise_dn = o.noise_sigma;
  if (o.noise_sigma == 0.0) ic.shot_noise_dn = 0.0;
  ic.seed = o.seed;

  dsp::SyntheticImuConfig imu_config;
  imu_config.rate_hz = o.imu_rate_hz;
  imu_config.noise = rig.imu;
  imu_config.seed = o.seed;
  imu_config.clock_offset_ns = static_cast<DurationNs>(std::llround(o.time_offset_ms * 1e6));
  // The calibration a user would have: imu0/sensor.yaml carries the offset (timeshift_cam_imu).
  calib.imu.timeshift_cam_imu_ns = imu_config.clock_offset_ns;
  dsp::draw_initial_biases(imu_config, o.seed);
  if (o.magnetometer) dsp::draw_magnetometer_iron(imu_config, o.seed);

  const std::size_t frames =
      static_cast<std::size_t>(std::floor(o.duration_s * o.camera_rate_hz + 1e-6));
  auto frame_t_ns = [&](std::size_t k) {
    return o.t0_ns +
           static_cast<TimeNs>(std::llround(static_cast<double>(k) * 1e9 / o.camera_rate_hz));
  };
  const TimeNs t_end_ns = frame_t_ns(frames - 1) + kImuTailNs;
  const std::vector<double> gains =
      dsp::auto_exposure_gains(frames, o.camera_rate_hz, o.gain_steps, o.seed);

  const fs::path part = out.string() + ".part";
  fs::remove_all(part, ec);  // a stale one from an interrupted run
  const fs::path mav0 = part / "mav0";
  const fs::path gt_dir = mav0 / "state_groundtruth_estimate0";
  nlohmann::json summary;
  try {
    recording::EurocWriterOptions writer_options;
    writer_options.fast_png = true;  // compression would cost more than the rendering
    recording::EurocWriter writer(part, calib, writer_options);
    fs::create_directories(gt_dir, ec);
    if (ec) throw_input_error(gt_dir.string(), 0, "cannot create folder: " + ec.message());
    RowFile gt(gt_dir / "data.csv", recording::ground_truth_csv_header());
    RowFile frame_rows(gt_dir / "camera_frames.csv",
                       "#timestamp [ns],gain,exposure [ns],blur_samples,motion_px\n");

    dsp::SyntheticImu imu(model, imu_config, o.t0_ns, o.t0_ns - kImuLeadNs);
    dsp::SyntheticImuRow last;
    std::size_t gt_rows = 0;
    double peak_rate = 0.0, speed_sum = 0.0, speed_max = 0.0;
    std::size_t speed_n = 0;
    const double moving_from_s = mc.still_start_s + mc.ramp_s;
    auto ground_truth = [&](TimeNs t_ns, const dsp::BodyMotionState& s) {
      recording::GroundTruthState g;
      g.t_ns = t_ns;
      g.T_world_body = s.T_world_body;
      g.vel_world_m_s = s.vel_world_m_s;
      g.gyro_bias_rad_s = last.gyro_bias_rad_s;
      g.accel_bias_m_s2 = last.accel_bias_m_s2;
      gt.write(recording::format_ground_truth_row(g));
      ++gt_rows;
      peak_rate = std::max(peak_rate, s.omega_body_rad_s.norm());
      if (s.t_s >= moving_from_s) {
        const double v = s.vel_world_m_s.head<2>().norm();
        speed_sum += v;
        speed_max = std::max(speed_max, v);
        ++speed_n;
      }
    };
    auto imu_until = [&](TimeNs t_ns) {
      while (imu.next_truth_t_ns() <= t_ns) {
        last = imu.next();
        writer.write_imu(last.sample);
        if (!o.ground_truth_at_camera_rate) ground_truth(last.truth_t_ns, last.truth);
      }
    };

    Image left = Image::allocate(o.width_px, o.height_px, PixelFormat::kGray8);
    Image right = Image::allocate(o.width_px, o.height_px, PixelFormat::kGray8);
    const std::size_t n_px =
        static_cast<std::size_t>(o.width_px) * static_cast<std::size_t>(o.height_px);
    std::vector<float> scratch;
    const dsp::CameraPoseFn T_world_cam0 = [&](double t_s) {
      return model.T_world_body(t_s) * rig.T_body_cam0;
    };
    long long blur_sum = 0;
    int blur_max = 0;
    bool interrupted = false;
    for (std::size_t k = 0; k < frames; ++k) {
      if (stop.load()) {
        interrupted = true;
        break;
      }
      const TimeNs t_ns = frame_t_ns(k);
      imu_until(t_ns);
      const double t_s = static_cast<double>(t_ns - o.t0_ns) * 1e-9;
      if (o.ground_truth_at_camera_rate) ground_truth(t_ns, model.state(t_s));
      if (o.imu_only) continue;
      const dsp::FrameFormation f =
          dsp::form_stereo_frame(room, rig.camera, T_world_cam0, t_s, gains[k], k, ic,
                                 std::span<std::uint8_t>(left.mutable_data(), n_px),
                                 std::span<std::uint8_t>(right.mutable_data(), n_px), scratch);
      blur_sum += f.blur_samples;
      blur_max = std::max(blur_max, f.blur_samples);
      writer.write_camera(0, CameraFrame{t_ns, 0, k, left});
      writer.write_camera(1, CameraFrame{t_ns, 0, k, right});
      frame_rows.write(std::to_string(t_ns) + "," + yaml_num(gains[k]) + "," +
                       std::to_string(std::llround(ic.exposure_s * 1e9 * (o.blur ? 1 : 0))) + "," +
                       std::to_string(f.blur_samples) + "," + yaml_num(f.motion_px) + "\n");
    }
    if (interrupted) {
      writer.close();
      fs::remove_all(part, ec);
      return {{"interrupted", true}};
    }
    imu_until(t_end_ns);
    writer.close();
    gt.close();
    frame_rows.close();

    const DurationNs offset_ns = imu_config.clock_offset_ns;
    write_text(mav0 / "camchain-imucam.yaml",
               camchain_yaml(calib, rig.camera.baseline_m, offset_ns));
    const auto& rb = room;
    std::string yaml = "%YAML:1.0\nsensor_type: visual-inertial\n";
    yaml += "comment: ground truth of wallar eval synth-rig (exact, not measured)\n";
    yaml +=
        "T_BS:\n  cols: 4\n  rows: 4\n  data: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, "
        "1.0, 0.0, 0.0, 0.0, 0.0, 1.0]\n";
    yaml += "generator: wallar eval synth-rig\n";
    yaml += "motion: " + std::string(dsp::to_string(o.motion)) + "\n";
    yaml += "seed: " + std::to_string(o.seed) + "\n";
    yaml += "duration_s: " + yaml_num(o.duration_s) + "\n";
    yaml += "camera_rate_hz: " + yaml_num(o.camera_rate_hz) +
            "\nimu_rate_hz: " + yaml_num(o.imu_rate_hz) + "\n";
    yaml += "imu_clock_offset_ns: " + std::to_string(offset_ns) +
            "  # IMU stamp = true time + this; timeshift_cam_imu in ../camchain-imucam.yaml\n";
    yaml += "timeshift_cam_imu: " + yaml_num(static_cast<double>(offset_ns) * 1e-9) + "  # [s]\n";
    yaml += "ground_truth_rate: " + std::string(o.ground_truth_at_camera_rate ? "camera" : "imu") +
            "\n";
    yaml += "exposure_ns: " + std::to_string(std::llround(ic.exposure_s * 1e9)) + "\n";
    yaml += "blur: " + std::string(o.blur ? "on" : "off") + "\n";
    yaml += "rolling_shutter_ns: " + std::to_string(std::llround(ic.rolling_shutter_s * 1e9)) +
            "  # first row to last; a frame's stamp is its middle row's mid-exposure\n";
    yaml += "gain_steps: " + std::string(o.gain_steps ? "on" : "off") + "\n";
    yaml += "read_noise_dn: " + yaml_num(ic.read_noise_dn) +
            "\nshot_noise_dn: " + yaml_num(ic.shot_noise_dn) + "\n";
    yaml += "peak_turn_deg_s: " + yaml_num(o.peak_turn_deg_s) + "\n";
    yaml += "walk_speed_m_s: " + yaml_num(mc.walk_speed_m_s) + "\n";
    yaml +=
        "still_start_s: " + yaml_num(mc.still_start_s) + "\nramp_s: " + yaml_num(mc.ramp_s) + "\n";
    yaml += "gravity_m_s2: " + yaml_num(imu_config.gravity_m_s2) + "\n";
    const auto vec = [](const Eigen::Vector3d& v) {
      return "[" + yaml_num(v.x()) + ", " + yaml_num(v.y()) + ", " + yaml_num(v.z()) + "]";
    };
    yaml += "gyro_bias0_rad_s: " + vec(imu_config.gyro_bias0_rad_s) + "\n";
    yaml += "accel_bias0_m_s2: " + vec(imu_config.accel_bias0_m_s2) + "\n";
    if (o.magnetometer) {
      const dsp::SyntheticMagnetometerConfig& m = imu_config.mag;
      yaml += "magnetic_field_world_uT: " + vec(m.field_world_uT) + "\n";
      yaml += "magnetometer_hard_iron_uT: " + vec(m.hard_iron_uT) + "\n";
      yaml += "magnetometer_soft_iron: [";
      for (int i = 0; i < 9; ++i) yaml += (i ? ", " : "") + yaml_num(m.soft_iron(i / 3, i % 3));
      yaml += "]  # row-major: reading = soft_iron * field_body + hard_iron + noise\n";
      yaml += "magnetometer_noise_uT: " + yaml_num(m.noise_uT) +
              "\nmagnetometer_every_n_samples: " + std::to_string(m.every_n_samples) + "\n";
    }
    yaml += "images: " + std::string(o.imu_only ? "none" : "stereo") + "\n";
    yaml += "room_m: [" + yaml_num(rb.x_min_m) + ", " + yaml_num(rb.x_max_m) + ", " +
            yaml_num(rb.y_min_m) + ", " + yaml_num(rb.y_max_m) + ", 0.0, " + yaml_num(rb.z_max_m) +
            "]  # x_min x_max y_min y_max z_min z_max\n";
    yaml += "texture_seed: " + std::to_string(rb.texture_seed) + "\n";
    write_text(gt_dir / "sensor.yaml", yaml);
    write_text(gt_dir / "README.md",
               "# Ground truth of a synthetic headset recording\n\n"
               "Written by `wallar eval synth-rig` (" +
                   std::string(dsp::to_string(o.motion)) + ", seed " + std::to_string(o.seed) +
                   "); exact, from the trajectory model, not measured.\n\n"
                   "- `data.csv`: EuRoC columns: T_world_body (p, q wxyz), v_world, gyro and "
                   "accelerometer biases, at the IMU's sample times (or the frames' with "
                   "ground_truth_rate: camera).\n"
                   "- World: z up, gravity along -z, floor at z = 0; body = the IMU frame; "
                   "cameras through T_BS in cam0/ and cam1/sensor.yaml.\n"
                   "- Clocks: camera stamps and these rows are true time. The IMU's clock runs "
                   "`imu_clock_offset_ns` = " +
                   std::to_string(offset_ns) +
                   " ns ahead: an IMU sample taken at true time t is stamped t + offset "
                   "(Kalibr's `timeshift_cam_imu` in ../camchain-imucam.yaml).\n"
                   "- `camera_frames.csv`: per frame the auto-exposure gain, exposure, the "
                   "sub-frames averaged for motion blur and the image motion during the exposure.\n"
                   "- `sensor.yaml`: every generator parameter.\n");
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    summary = {
        {"out", out.string()},
        {"motion", std::string(dsp::to_string(o.motion))},
        {"seed", o.seed},
        {"frames", writer.frames_written(0)},
        {"imu_rows", writer.imu_written()},
        {"magnetometer_rows", writer.mag_written()},
        {"ground_truth_rows", gt_rows},
        {"width", o.width_px},
        {"height", o.height_px},
        {"focal_px", rig.camera.f_px},
        {"imu_clock_offset_ns", offset_ns},
        {"peak_angular_rate_deg_s", peak_rate * kRadToDeg},
        {"mean_horizontal_speed_m_s", speed_n > 0 ? speed_sum / static_cast<double>(speed_n) : 0.0},
        {"max_horizontal_speed_m_s", speed_max},
        {"blur_samples_mean", static_cast<double>(blur_sum) / static_cast<double>(frames)},
        {"blur_samples_max", blur_max},
        {"seconds", wall_s},
        {"cpu_seconds", cpu_seconds() - cpu0}};
  } catch (...) {
    fs::remove_all(part, ec);
    throw;
  }
  fs::rename(part, out, ec);
  if (ec) {
    const std::string why = ec.message();
    fs::remove_all(part, ec);
    throw_input_error(out.string(), 0, "cannot rename " + part.string() + " into place: " + why);
  }
  return summary;
}

}  // namespace wallar::eval
