// SPDX-License-Identifier: Apache-2.0
/// @file cmd_calibrate.cpp
/// @brief `wallar calibrate imu-cam RECORDING`: the IMU-to-left-camera rotation and the
/// camera-IMU time offset from the gyro against the images, compared with the recording's
/// calibration, and written as the rig file a board points at (--out); `calibrate imu-noise`
/// (Allan deviation at rest) and `calibrate accel-mag` (accelerometer bias, magnetometer iron).
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/eval/output.hpp"
#include "wallar/firmware/accel_mag_calibration.hpp"
#include "wallar/firmware/imu_cam_calibration.hpp"
#include "wallar/firmware/imu_noise_calibration.hpp"
#include "wallar/firmware/offline.hpp"

namespace wallar::cli {
namespace {

// A measured figure, or null where there is none.
nlohmann::json json_or_null(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

struct ImuCamArgs {
  std::string recording;
  std::string out;        // the rig file to write
  std::string imu;        // the IMU's noise (`calibrate imu-noise --out`), into the rig file
  std::string cameras;    // the cameras (`calibrate stereo --out/--kalibr`): tracked with them
  bool pairwise = false;  // rotations from image pairs instead of the tracker
  firmware::ImuCamCalibrationParams params;
  bool json = false;
};

// The recording's rig with the IMU placed as calibrated: its rotation into cam0 the solved one,
// its position kept from the recording (rotations do not show where the IMU sits; a few
// centimetres matter little to the attitude filter and the gyro prior), its clock offset.
RigCalibration calibrated_rig(const recording::EurocRecording& rec,
                              const firmware::ImuCamCalibration& c) {
  RigCalibration rig = rec.rig();
  SE3d T_cam0_imu = rig.T_cam0_imu();
  T_cam0_imu.linear() = c.solved.R_cam_imu;
  rig.imu.T_body_imu = rig.cams[0].T_body_cam * T_cam0_imu;
  rig.imu.timeshift_cam_imu_ns = c.timeshift_cam_imu_ns;
  rig.imu_extrinsic_known = true;
  return rig;
}

// The cameras of a stereo calibration (`calibrate stereo`: intrinsics, distortion, cam0 ->
// cam1) in place of the recording's, placed in its body frame as its cam0 is (the IMU's
// position in the rig file stays the recording's), so the tracking and the rig file use them.
void use_cameras(const RigCalibration& from, const std::string& file,
                 recording::EurocRecording& rec) {
  for (std::size_t i = 0; i < 2; ++i) {
    const CameraCalibration& c = from.cams[i];
    const CameraCalibration& r = rec.cams[i].calib;
    if (c.width_px != r.width_px || c.height_px != r.height_px) {
      throw InputError(file + ": --cameras: cam" + std::to_string(i) + " is " +
                       std::to_string(c.width_px) + "x" + std::to_string(c.height_px) +
                       " but the recording's images are " + std::to_string(r.width_px) + "x" +
                       std::to_string(r.height_px));
    }
  }
  const SE3d T_body_cam0 = rec.cams[0].calib.T_body_cam;
  const SE3d T_cam0_cam1 = from.T_cam0_cam1();
  for (std::size_t i = 0; i < 2; ++i) {
    CameraCalibration c = from.cams[i];
    c.name = rec.cams[i].calib.name;
    if (c.rate_hz <= 0.0) c.rate_hz = rec.cams[i].calib.rate_hz;  // OpenCV's file has none
    c.T_body_cam = i == 0 ? T_body_cam0 : T_body_cam0 * T_cam0_cam1;
    rec.cams[i].calib = c;
  }
}

int run_imu_cam(const ImuCamArgs& a) {
  if (!a.imu.empty() && a.out.empty())
    throw InputError("--imu: goes into the rig file: give --out");
  // Read first: a bad noise file is said before minutes of tracking.
  std::optional<ImuCalibration> noise;
  if (!a.imu.empty()) {
    noise = recording::read_imu_sensor_yaml(a.imu);
    if (!(noise->gyro_noise_density > 0.0 && noise->accel_noise_density > 0.0)) {
      throw InputError(a.imu + ": --imu: no gyroscope and accelerometer noise densities");
    }
  }
  std::optional<RigCalibration> cameras;
  if (!a.cameras.empty()) cameras = recording::read_rig_calibration(a.cameras);
  recording::ReadOptions options;
  options.check_image_files = true;
  recording::EurocRecording rec = read_recording_reporting(a.recording, options);
  if (cameras) use_cameras(*cameras, a.cameras, rec);
  firmware::ImuCamCalibration c;
  if (a.pairwise) {
    c = firmware::calibrate_imu_cam(rec, a.params);
  } else {
    // cam0's rotations from the stereo tracker, run over the recording vision-only (the gyro
    // prior would take the very transform being calibrated), frame by frame.
    firmware::ApplianceOptions run = firmware::offline_options(firmware::ApplianceMode::kLockStep);
    run.use_gyro = false;
    const firmware::ApplianceReport report =
        firmware::run_over_recording(rec, firmware::BoardConfig{}, run, stop_requested());
    c = firmware::calibrate_imu_cam(rec, report.trajectory, a.params);
  }
  const Eigen::Matrix3d& R = c.solved.R_cam_imu;
  const Eigen::Quaterniond q(R);
  nlohmann::json j = {
      {"recording", a.recording},
      {"R_cam_imu",
       {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)}},
      {"q_cam_imu_wxyz", {q.w(), q.x(), q.y(), q.z()}},
      {"pairs_used", c.solved.pairs},
      {"frame_pairs", c.frame_pairs},
      {"turning_pairs", c.turning_pairs},
      {"visual_failures", c.visual_failures},
      {"angle_mismatches", c.angle_mismatches},
      {"residual_rms_deg", c.solved.residual_rms_rad * 180.0 / M_PI},
      {"min_axis_spread", c.solved.min_axis_spread},
      {"gyro_bias_from_still_window", c.bias_from_still_window},
      {"vs_calibration_deg", c.vs_calibration_deg},
      {"camera_rotations", c.from_track ? "tracked" : "image pairs"},
      {"time_offset_estimated", c.time_offset_estimated},
      {"timeshift_cam_imu_ms", static_cast<double>(c.timeshift_cam_imu_ns) * 1e-6}};
  if (!a.out.empty()) {
    // One rig file the board points at: both cameras, T_cam_imu and the time offset (Kalibr's
    // camchain-imucam layout, which `calibration:` in a board file reads), and the IMU's noise:
    // measured at rest (--imu), else the recording's.
    RigCalibration rig = calibrated_rig(rec, c);
    if (noise) {
      rig.imu.rate_hz = noise->rate_hz;
      rig.imu.gyro_noise_density = noise->gyro_noise_density;
      rig.imu.gyro_random_walk = noise->gyro_random_walk;
      rig.imu.accel_noise_density = noise->accel_noise_density;
      rig.imu.accel_random_walk = noise->accel_random_walk;
      // And the accelerometer bias and magnetometer iron, where `calibrate accel-mag` put them.
      rig.imu.accel_bias_m_s2 = noise->accel_bias_m_s2;
      rig.imu.mag_hard_iron_uT = noise->mag_hard_iron_uT;
      rig.imu.mag_soft_iron = noise->mag_soft_iron;
      j["imu_noise_from"] = a.imu;
    }
    eval::write_file_atomically(a.out, recording::format_kalibr_camchain(rig, true));
    j["out"] = a.out;
  }
  if (a.json) {
    std::cout << j.dump(2) << "\n";
    return kExitOk;
  }
  std::printf(
      "wallar calibrate imu-cam: %zu of %zu frame pairs used (%zu turning), residual %.3f "
      "deg RMS, axis spread %.2f\nR_cam_imu =\n",
      c.solved.pairs, c.frame_pairs, c.turning_pairs, c.solved.residual_rms_rad * 180.0 / M_PI,
      c.solved.min_axis_spread);
  for (int i = 0; i < 3; ++i) std::printf("  [%+.6f %+.6f %+.6f]\n", R(i, 0), R(i, 1), R(i, 2));
  std::printf("%.3f deg from the recording's cam0 calibration (T_BS)\n", c.vs_calibration_deg);
  if (c.time_offset_estimated) {
    std::printf("camera-IMU time offset: t_imu = t_cam %+.2f ms\n",
                static_cast<double>(c.timeshift_cam_imu_ns) * 1e-6);
  }
  if (!a.out.empty()) std::printf("rig written to %s\n", a.out.c_str());
  return kExitOk;
}

struct ImuNoiseArgs {
  std::string recording;
  std::string out;  // an imu0/sensor.yaml to write
  double min_duration_s = 60.0;
  bool json = false;
};

int run_imu_noise(const ImuNoiseArgs& a) {
  const recording::EurocRecording rec = recording::read_recording_imu(a.recording);
  const firmware::ImuNoiseCalibration c = firmware::calibrate_imu_noise(rec, a.min_duration_s);
  const auto axes = [&](const std::array<dsp::AllanNoise, 3>& n) {
    nlohmann::json j = nlohmann::json::array();
    for (const dsp::AllanNoise& x : n) {
      j.push_back({{"noise_density", json_or_null(x.white_density)},
                   {"random_walk", json_or_null(x.random_walk)},
                   {"bias_instability", x.bias_instability},
                   {"tau_min_s", x.tau_min_s}});
    }
    return j;
  };
  const ImuCalibration& file = rec.imu_calib;
  nlohmann::json j = {{"recording", a.recording},
                      {"duration_s", c.duration_s},
                      {"rate_hz", c.rate_hz},
                      {"gyroscope_noise_density", json_or_null(c.gyro_noise_density)},
                      {"gyroscope_random_walk", json_or_null(c.gyro_random_walk)},
                      {"accelerometer_noise_density", json_or_null(c.accel_noise_density)},
                      {"accelerometer_random_walk", json_or_null(c.accel_random_walk)},
                      {"gyro_axes", axes(c.gyro)},
                      {"accel_axes", axes(c.accel)},
                      {"sensor_yaml",
                       {{"gyroscope_noise_density", file.gyro_noise_density},
                        {"gyroscope_random_walk", file.gyro_random_walk},
                        {"accelerometer_noise_density", file.accel_noise_density},
                        {"accelerometer_random_walk", file.accel_random_walk}}}};
  if (!a.out.empty()) {
    // The recording's IMU description with what was measured in place of what it said; a
    // random walk the recording was too short to show keeps the file's value.
    ImuCalibration imu = file;
    imu.rate_hz = c.rate_hz;
    if (c.gyro_noise_density) imu.gyro_noise_density = *c.gyro_noise_density;
    if (c.gyro_random_walk) imu.gyro_random_walk = *c.gyro_random_walk;
    if (c.accel_noise_density) imu.accel_noise_density = *c.accel_noise_density;
    if (c.accel_random_walk) imu.accel_random_walk = *c.accel_random_walk;
    recording::write_imu_sensor_yaml(a.out, imu);
    j["out"] = a.out;
  }
  if (a.json) {
    std::cout << j.dump(2) << "\n";
    return kExitOk;
  }
  const auto show = [](const char* name, const std::optional<double>& v, double file_value,
                       const char* unit) {
    if (v) {
      std::printf("  %-28s %.3e %s (the recording's sensor.yaml: %.3e)\n", name, *v, unit,
                  file_value);
    } else {
      std::printf("  %-28s not identifiable: record longer (the +1/2 slope never shows)\n", name);
    }
  };
  std::printf("wallar calibrate imu-noise: %.1f s at %.1f Hz, Allan deviation per axis\n",
              c.duration_s, c.rate_hz);
  show("gyroscope_noise_density", c.gyro_noise_density, file.gyro_noise_density, "rad/s/sqrt(Hz)");
  show("gyroscope_random_walk", c.gyro_random_walk, file.gyro_random_walk, "rad/s^2/sqrt(Hz)");
  show("accelerometer_noise_density", c.accel_noise_density, file.accel_noise_density,
       "m/s^2/sqrt(Hz)");
  show("accelerometer_random_walk", c.accel_random_walk, file.accel_random_walk, "m/s^3/sqrt(Hz)");
  if (!a.out.empty()) std::printf("written to %s\n", a.out.c_str());
  return kExitOk;
}

struct AccelMagArgs {
  std::string recording;
  std::string imu;  // the sensor.yaml to start from (`calibrate imu-noise --out`)
  std::string out;  // the sensor.yaml to write
  firmware::AccelMagCalibrationParams params;
  bool json = false;
};

nlohmann::json vec_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

int run_accel_mag(const AccelMagArgs& a) {
  std::optional<ImuCalibration> base;
  if (!a.imu.empty()) base = recording::read_imu_sensor_yaml(a.imu);
  const recording::EurocRecording rec = recording::read_recording_imu(a.recording);
  const firmware::AccelMagCalibration c = firmware::calibrate_accel_mag(rec, a.params);
  const std::string where = (rec.mav0 / "imu0").string();
  std::string accel_why;
  if (!c.accel.solved) {
    char msg[200];
    if (c.poses.size() < 4) {
      std::snprintf(msg, sizeof msg,
                    "%zu still poses found: hold the headset still (a second each) in at least "
                    "four tilts: level, forward, back, left, right",
                    c.poses.size());
    } else {
      std::snprintf(msg, sizeof msg,
                    "the %zu still poses do not tilt about every axis (spread %.3f, needs %.2f): "
                    "hold it tilted forward, back, left and right too",
                    c.poses.size(), c.accel.direction_spread, dsp::kMinAccelDirectionSpread);
    }
    accel_why = msg;
  }
  std::string mag_why;
  if (c.mag && !c.mag->solved) {
    char msg[200];
    std::snprintf(msg, sizeof msg,
                  "the %zu magnetometer readings cover too few directions (coverage %.3f, needs "
                  "%.2f): turn the headset round at several tilts",
                  c.mag_samples, c.mag->coverage, dsp::kMinMagCoverage);
    mag_why = msg;
  }
  nlohmann::json j = {{"recording", a.recording},
                      {"duration_s", c.duration_s},
                      {"imu_samples", c.samples},
                      {"still_poses", c.poses.size()},
                      {"gravity_m_s2", a.params.gravity_m_s2}};
  j["accelerometer"] = {{"solved", c.accel.solved},
                        {"bias_m_s2", vec_json(c.accel.bias_m_s2)},
                        {"residual_rms_m_s2", c.accel.residual_rms_m_s2},
                        {"direction_spread", c.accel.direction_spread}};
  if (!accel_why.empty()) j["accelerometer"]["why"] = accel_why;
  if (c.accel_bias_truth_m_s2) {
    j["accelerometer"]["truth_bias_m_s2"] = vec_json(*c.accel_bias_truth_m_s2);
    j["accelerometer"]["bias_error_m_s2"] = (c.accel.bias_m_s2 - *c.accel_bias_truth_m_s2).norm();
    j["accelerometer"]["tilt_error_raw_deg"] = json_or_null(c.tilt_error_raw_deg);
    j["accelerometer"]["tilt_error_deg"] = json_or_null(c.tilt_error_deg);
  }
  if (c.mag) {
    const Eigen::Matrix3d& S = c.mag->soft_iron;
    j["magnetometer"] = {
        {"solved", c.mag->solved},
        {"readings", c.mag_samples},
        {"hard_iron_uT", vec_json(c.mag->hard_iron_uT)},
        {"soft_iron",
         {S(0, 0), S(0, 1), S(0, 2), S(1, 0), S(1, 1), S(1, 2), S(2, 0), S(2, 1), S(2, 2)}},
        {"field_uT", c.mag->field_uT},
        {"residual_rms_uT", c.mag->residual_rms_uT},
        {"coverage", c.mag->coverage},
        {"heading_spread_raw_deg", json_or_null(c.heading_spread_raw_deg)},
        {"heading_spread_deg", json_or_null(c.heading_spread_deg)}};
    if (!mag_why.empty()) j["magnetometer"]["why"] = mag_why;
  } else {
    j["magnetometer"] = nullptr;
  }
  if (!a.out.empty()) {
    // A file with a part that failed would pass for a calibration: refuse it, say which part.
    if (!accel_why.empty()) throw_input_error(where, 0, "--out: accelerometer: " + accel_why);
    if (!mag_why.empty()) throw_input_error(where, 0, "--out: magnetometer: " + mag_why);
    ImuCalibration imu = base ? *base : rec.imu_calib;
    if (imu.rate_hz <= 0.0) imu.rate_hz = static_cast<double>(c.samples - 1) / c.duration_s;
    imu.accel_bias_m_s2 = c.accel.bias_m_s2;
    if (c.mag) {
      imu.mag_hard_iron_uT = c.mag->hard_iron_uT;
      imu.mag_soft_iron = c.mag->soft_iron;
    }
    recording::write_imu_sensor_yaml(a.out, imu);
    j["out"] = a.out;
  }
  const auto unsolved = [&] {
    std::fprintf(stderr, "wallar: %s: accelerometer bias not solved: %s\n", where.c_str(),
                 accel_why.c_str());
    return kExitBadInput;
  };
  if (a.json) {
    std::cout << j.dump(2) << "\n";
    return c.accel.solved ? kExitOk : unsolved();
  }
  std::printf("wallar calibrate accel-mag: %.1f s, %zu IMU samples, %zu still poses\n",
              c.duration_s, c.samples, c.poses.size());
  if (c.accel.solved) {
    const Eigen::Vector3d& b = c.accel.bias_m_s2;
    std::printf(
        "  accelerometer bias [%+.4f %+.4f %+.4f] m/s^2 (|a - b| - g: %.4f m/s^2 RMS, spread "
        "%.2f)\n",
        b.x(), b.y(), b.z(), c.accel.residual_rms_m_s2, c.accel.direction_spread);
  } else {
    std::printf("  accelerometer bias: not solved: %s\n", accel_why.c_str());
  }
  if (!c.mag) {
    std::printf("  magnetometer: the recording has no readings (mag0/data.csv)\n");
  } else if (c.mag->solved) {
    const Eigen::Vector3d& h = c.mag->hard_iron_uT;
    std::printf(
        "  magnetometer hard iron [%+.2f %+.2f %+.2f] uT, field %.2f uT (%.3f uT RMS), "
        "coverage %.2f\n",
        h.x(), h.y(), h.z(), c.mag->field_uT, c.mag->residual_rms_uT, c.mag->coverage);
  } else {
    std::printf("  magnetometer: not solved: %s\n", mag_why.c_str());
  }
  if (c.heading_spread_raw_deg && c.heading_spread_deg) {
    std::printf("  heading spread against the ground truth: %.2f deg as read, %.2f corrected\n",
                *c.heading_spread_raw_deg, *c.heading_spread_deg);
  }
  if (!a.out.empty()) std::printf("written to %s\n", a.out.c_str());
  return c.accel.solved ? kExitOk : unsolved();
}

}  // namespace

void add_calibrate_command(CLI::App& app, std::function<int()>& run) {
  CLI::App* calibrate = app.add_subcommand("calibrate", "Calibrations estimated from a recording");
  calibrate->require_subcommand(1);
  auto a = std::make_shared<ImuCamArgs>();
  CLI::App* cmd = calibrate->add_subcommand(
      "imu-cam",
      "IMU-to-left-camera rotation from gyro vs image rotations (the camera must turn about two "
      "axes)");
  cmd->add_option("recording", a->recording, "Recording with cam0 and imu0 (EuRoC folder or .mcap)")
      ->required();
  cmd->add_option("--step", a->params.frame_step, "Pair frame k with frame k + STEP")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_option("--min-rotation", a->params.min_rotation_deg,
                  "Least gyro rotation of a pair to use it [deg]")
      ->check(CLI::Range(0.1, 90.0))
      ->capture_default_str();
  cmd->add_option("--min-pairs", a->params.min_pairs, "Fewest pairs to solve")
      ->check(CLI::Range(2, 100000))
      ->capture_default_str();
  cmd->add_option("--max-offset-ms", a->params.max_time_offset_ms,
                  "Search the camera-IMU time offset within +-this [ms] (0: the clocks are "
                  "synchronised)")
      ->check(CLI::Range(0.0, 200.0))
      ->capture_default_str();
  cmd->add_flag("--pairwise", a->pairwise,
                "The camera's rotations from each image pair alone (rotation-only fit) instead "
                "of from the stereo tracker over the whole recording");
  cmd->add_option("--out", a->out,
                  "Write the rig file (Kalibr camchain with T_cam_imu and timeshift_cam_imu) "
                  "for the board's calibration: key");
  cmd->add_option("--cameras", a->cameras,
                  "The cameras from `calibrate stereo` (its --out or --kalibr file) instead of "
                  "the recording's: tracked with them and written to the rig file");
  cmd->add_option("--imu", a->imu,
                  "The IMU's noise for the rig file: `calibrate imu-noise --out`'s sensor.yaml "
                  "(default: the recording's)");
  cmd->add_flag("--json", a->json, "Print the result as JSON on stdout");
  cmd->callback([a, &run] { run = [a] { return run_imu_cam(*a); }; });
  auto n = std::make_shared<ImuNoiseArgs>();
  CLI::App* noise = calibrate->add_subcommand(
      "imu-noise",
      "The IMU's noise densities and random walks from a recording of it at rest (Allan "
      "deviation)");
  noise
      ->add_option("recording", n->recording,
                   "Recording with imu0, at rest (EuRoC folder or .mcap)")
      ->required();
  noise->add_option("--min-duration-s", n->min_duration_s, "Shortest recording accepted [s]")
      ->check(CLI::Range(10.0, 1e6))
      ->capture_default_str();
  noise->add_option("--out", n->out,
                    "Write an imu0/sensor.yaml with the measured densities (Kalibr's names)");
  noise->add_flag("--json", n->json, "Print the result as JSON on stdout");
  noise->callback([n, &run] { run = [n] { return run_imu_noise(*n); }; });
  auto am = std::make_shared<AccelMagArgs>();
  CLI::App* accel_mag = calibrate->add_subcommand(
      "accel-mag",
      "The accelerometer's bias (from still poses in several tilts) and the magnetometer's hard "
      "and soft iron (an ellipsoid fit) from a recording of the headset held in tilts and turned "
      "round");
  accel_mag
      ->add_option("recording", am->recording,
                   "Recording with imu0 (and mag0 for the magnetometer), EuRoC folder or .mcap")
      ->required();
  accel_mag
      ->add_option("--gravity", am->params.gravity_m_s2,
                   "Local gravity the still poses are held to [m/s^2]")
      ->check(CLI::Range(9.7, 9.9))
      ->capture_default_str();
  accel_mag
      ->add_option("--field-uT", am->params.field_uT,
                   "Local magnetic field strength [uT] (0: keep the sensor's own scale)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  accel_mag->add_option("--imu", am->imu,
                        "Start from this imu0/sensor.yaml (`calibrate imu-noise --out`): --out "
                        "keeps its noise figures");
  accel_mag->add_option(
      "--out", am->out,
      "Write an imu0/sensor.yaml with the bias and iron (for `calibrate imu-cam --imu`)");
  accel_mag->add_flag("--json", am->json, "Print the result as JSON on stdout");
  accel_mag->callback([am, &run] { run = [am] { return run_accel_mag(*am); }; });
  add_calibrate_stereo_commands(*calibrate, run);
}

}  // namespace wallar::cli
