// SPDX-License-Identifier: Apache-2.0
/// @file cmd_eval_synth_rig.cpp
/// @brief `wallar eval synth-rig --out DIR`: a synthetic moving-headset recording in the EuRoC
/// layout (tools/eval/synth_rig.hpp), for `wallar track DIR --eval` and the IMU tools.
#include <charconv>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/eval/synth_rig.hpp"

namespace wallar::cli {
namespace {

struct SynthRigArgs {
  eval::SynthRigOptions options;
  std::string out;
  std::string motion = "look-around";
  std::string blur = "on";
  std::string gain_steps = "off";
  std::string ground_truth = "imu";
  std::string imu_noise_from;
  bool peak_turn_given = false;
  bool json = false;
};

bool on_off(const std::string& option, const std::string& value) {
  if (value == "on") return true;
  if (value == "off") return false;
  throw InputError(option + ": must be on or off, got '" + printable(value) + "'");
}

// Everything that can be wrong on the command line is found here, before a file is written.
eval::SynthRigOptions options_of(const SynthRigArgs& a) {
  eval::SynthRigOptions o = a.options;
  const auto motion = dsp::head_motion_named(a.motion);
  if (!motion) {
    std::string names;
    for (const std::string_view n : dsp::kHeadMotionNames)
      names += (names.empty() ? "" : ", ") + std::string(n);
    throw InputError("--motion: must be one of " + names + ", got '" + printable(a.motion) + "'");
  }
  o.motion = *motion;
  if (a.peak_turn_given && o.motion != dsp::HeadMotion::kQuickTurns &&
      o.motion != dsp::HeadMotion::kWalkTurns) {
    throw InputError("--peak-turn-deg-s: applies to --motion quick-turns and walk-turns only");
  }
  if (a.blur == "on" || a.blur == "off") {
    o.blur = a.blur == "on";
  } else {  // --blur MS: on, with that exposure
    double ms = 0.0;
    const char* end = a.blur.data() + a.blur.size();
    const auto r = std::from_chars(a.blur.data(), end, ms);
    if (r.ec != std::errc() || r.ptr != end) {
      throw InputError("--blur: must be on, off or an exposure in ms, got '" + printable(a.blur) +
                       "'");
    }
    o.blur = true;
    o.exposure_ms = ms;
  }
  o.gain_steps = on_off("--gain-steps", a.gain_steps);
  if (a.ground_truth != "imu" && a.ground_truth != "camera") {
    throw InputError("--ground-truth: must be imu or camera, got '" + printable(a.ground_truth) +
                     "'");
  }
  o.ground_truth_at_camera_rate = a.ground_truth == "camera";
  if (!a.imu_noise_from.empty()) {
    try {
      o.imu_noise = recording::read_imu_sensor_yaml(a.imu_noise_from);
    } catch (const InputError& e) {
      throw InputError(std::string("--imu-noise-from: ") + e.what());
    }
  }
  eval::check_synth_rig_options(o);
  return o;
}

int run_synth_rig(const SynthRigArgs& a) {
  const eval::SynthRigOptions o = options_of(a);
  const nlohmann::json j = eval::write_synth_rig(o, a.out, stop_requested());
  if (j.contains("interrupted")) {
    std::fprintf(stderr, "wallar: synth-rig interrupted; nothing written to %s\n", a.out.c_str());
    return kExitInterrupted;
  }
  if (a.json) {
    std::cout << j.dump(2) << "\n";
    return kExitOk;
  }
  std::printf(
      "wallar eval synth-rig: wrote %s (%s, seed %llu): %zu stereo frames %dx%d, %zu IMU rows, "
      "%zu ground-truth rows\n",
      a.out.c_str(), a.motion.c_str(), static_cast<unsigned long long>(o.seed),
      j["frames"].get<std::size_t>(), o.width_px, o.height_px, j["imu_rows"].get<std::size_t>(),
      j["ground_truth_rows"].get<std::size_t>());
  std::printf(
      "  peak angular rate %.1f deg/s, horizontal speed mean %.2f max %.2f m/s; blur sub-frames "
      "mean %.1f max %d; IMU clock offset %lld ns\n",
      j["peak_angular_rate_deg_s"].get<double>(), j["mean_horizontal_speed_m_s"].get<double>(),
      j["max_horizontal_speed_m_s"].get<double>(), j["blur_samples_mean"].get<double>(),
      j["blur_samples_max"].get<int>(), j["imu_clock_offset_ns"].get<long long>());
  std::printf("  %.1f s (%.1f s CPU)\n", j["seconds"].get<double>(),
              j["cpu_seconds"].get<double>());
  return kExitOk;
}

}  // namespace

void add_eval_synth_rig_command(CLI::App& eval, std::function<int()>& run) {
  auto a = std::make_shared<SynthRigArgs>();
  eval::SynthRigOptions& o = a->options;
  CLI::App* s = eval.add_subcommand(
      "synth-rig",
      "Write a synthetic moving-headset recording (EuRoC layout: stereo, IMU, ground truth)");
  s->add_option("--out", a->out, "Output folder (must not exist, or be empty)")->required();
  s->add_option("--motion", a->motion,
                "look-around, walk, quick-turns, room-loop, walk-turns (walking with quick "
                "glances aside) or calibration (held still in five tilts, turned round in "
                "quarter turns at each: for calibrate accel-mag and imu-cam)")
      ->capture_default_str();
  s->add_option("--duration", o.duration_s, "Length [s]")->capture_default_str();
  s->add_option("--camera-rate", o.camera_rate_hz, "Stereo frame rate [Hz]")->capture_default_str();
  s->add_option("--imu-rate", o.imu_rate_hz, "IMU rate, 200-1000 [Hz]")->capture_default_str();
  s->add_option("--seed", o.seed, "Random seed (texture, motion phases, noise)")
      ->capture_default_str();
  s->add_option("--blur", a->blur, "Motion blur: on, off, or on with this exposure [ms]")
      ->capture_default_str();
  s->add_option("--exposure-ms", o.exposure_ms, "Exposure time with --blur on [ms]")
      ->capture_default_str();
  s->add_option("--rolling-shutter", o.rolling_shutter_ms,
                "Rolling-shutter readout, first row to last [ms]; 0 = global shutter")
      ->capture_default_str();
  s->add_option("--gain-steps", a->gain_steps, "Auto-exposure gain steps every 2-5 s: on or off")
      ->capture_default_str();
  s->add_option("--noise", o.noise_sigma,
                "Read noise sigma [gray levels] (plus shot noise); 0 = noise-free images")
      ->capture_default_str();
  s->add_option("--time-offset-ms", o.time_offset_ms,
                "IMU clock minus camera clock [ms] (Kalibr's timeshift_cam_imu)")
      ->capture_default_str();
  s->add_option("--peak-turn-deg-s", o.peak_turn_deg_s,
                "quick-turns, walk-turns: peak rate of each turn")
      ->capture_default_str()
      ->each([a](const std::string&) { a->peak_turn_given = true; });
  s->add_option("--width", o.width_px, "Image width [px]")->capture_default_str();
  s->add_option("--height", o.height_px, "Image height [px]")->capture_default_str();
  s->add_option("--focal-px", o.focal_px, "Focal length [px] (default 450 * width / 640)");
  s->add_option("--ground-truth", a->ground_truth,
                "Ground-truth rows at the imu's sample times or the camera's frame times")
      ->capture_default_str();
  s->add_option("--imu-noise-from", a->imu_noise_from,
                "imu0/sensor.yaml whose noise densities and random walks the IMU gets");
  s->add_flag("--magnetometer", o.magnetometer,
              "A magnetometer on the IMU (mag0/data.csv), with hard and soft iron drawn from the "
              "seed (the truth in the ground truth's sensor.yaml)");
  s->add_flag("--imu-only", o.imu_only,
              "No images (an IMU recording for calibrate imu-noise and accel-mag)");
  s->add_flag("--json", a->json, "Print the summary as JSON");
  s->callback([a, &run] { run = [a] { return run_synth_rig(*a); }; });
}

}  // namespace wallar::cli
