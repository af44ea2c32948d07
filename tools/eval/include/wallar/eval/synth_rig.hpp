// SPDX-License-Identifier: Apache-2.0
/// @file synth_rig.hpp
/// @brief `wallar eval synth-rig` (issue 17, deliverable 6): a moving headset in the synthetic
/// room written as a EuRoC/ASL recording that read_euroc reads and `wallar track --eval`
/// evaluates. The computation is dsp/tracking/synthetic_motion.hpp; this writes it.
///
/// Layout written under OUT (first as OUT.part, renamed to OUT when complete, so an interrupted
/// or failed run leaves no recording that looks finished):
///   mav0/body.yaml, cam{0,1}/{data.csv, data/T.png, sensor.yaml}, imu0/{data.csv, sensor.yaml},
///   mag0/data.csv (with a magnetometer)
///   mav0/camchain-imucam.yaml   Kalibr's form: T_cam_imu, intrinsics, timeshift_cam_imu [s]
///   mav0/state_groundtruth_estimate0/
///     data.csv          T_world_body, v, gyro/accel biases at the IMU's sample times (or the
///                       frames' times), on the cameras' clock
///     sensor.yaml       EuRoC's T_BS plus every generator parameter, imu_clock_offset_ns among
///                       them
///     camera_frames.csv per frame: gain, exposure, sub-frames averaged, image motion
///     README.md         the clocks and frames in words
///
/// Clocks: camera stamps and ground truth are true time; an IMU sample taken at true time t is
/// stamped t + time_offset (timeshift_cam_imu = offset, Kalibr's t_imu = t_cam + shift).
/// Frames: world z up; body = IMU; the cameras through T_BS. The same options and seed give
/// byte-identical files.
///
/// Threading: write_synth_rig runs in the calling thread and shares no state.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>

#include "wallar/core/calibration.hpp"
#include "wallar/dsp/tracking/synthetic_motion.hpp"

namespace wallar::eval {

struct SynthRigOptions {
  dsp::HeadMotion motion = dsp::HeadMotion::kLookAround;
  double duration_s = 20.0;  //!< camera frames cover [0, duration)
  double camera_rate_hz = 20.0;
  double imu_rate_hz = 200.0;  //!< 200-1000
  std::uint64_t seed = 1;
  bool blur = true;
  double exposure_ms = 5.0;
  double rolling_shutter_ms = 0.0;  //!< readout, first row to last; 0 = global shutter
  bool gain_steps = false;
  double noise_sigma = 1.5;     //!< read noise [gray levels]; 0 = noise-free (no shot noise either)
  double time_offset_ms = 0.0;  //!< IMU clock minus camera clock
  double peak_turn_deg_s = 300.0;
  int width_px = 640, height_px = 480;
  double focal_px = 0.0;                     //!< 0: 450 * width / 640
  bool ground_truth_at_camera_rate = false;  //!< default: at the IMU's sample times
  /// The IMU's noise densities; default: dsp::default_headset_rig()'s (a consumer MEMS IMU).
  std::optional<ImuCalibration> imu_noise;
  /// A magnetometer on the IMU (mav0/mag0/data.csv) with hard and soft iron drawn from the seed
  /// (dsp::draw_magnetometer_iron); the truth goes into the ground truth's sensor.yaml.
  bool magnetometer = false;
  /// No images: cam0 and cam1 hold their sensor.yaml and a data.csv of its header only (an IMU
  /// recording for `calibrate imu-noise` and `calibrate accel-mag`, made in a fraction of the
  /// time).
  bool imu_only = false;
  /// The first camera frame's time stamp [ns].
  TimeNs t0_ns = 1'700'000'000'000'000'000;
};

/// Throws InputError with one line naming the option for any option out of range (before
/// anything is written): duration 0-3600 s, camera rate 1-120 Hz, IMU rate 200-1000 Hz and at
/// least the camera rate, exposure 0-1 frame period, rolling shutter 0-1 frame period, noise
/// 0-50, time offset +-1000 ms, peak turn rate 30-1500 deg/s, image 64-4096 x 48-4096 px,
/// focal length 0 (default) or 10-20000 px, negative densities.
void check_synth_rig_options(const SynthRigOptions& options);

/// The rig the options describe (image size, focal length, noise densities, rates).
[[nodiscard]] dsp::HeadsetRig synth_rig_headset(const SynthRigOptions& options);

/// Writes the recording to `out` (which must not exist, or be an empty folder) and returns a
/// summary: counts, the measured peak angular rate and horizontal speed of the ground truth, the
/// blur sub-frames, the offset, and how long it took. Stops early when `stop` is set: then the
/// partial OUT.part is removed and the summary says "interrupted": true. Throws InputError for
/// bad options or an output that cannot be written.
nlohmann::json write_synth_rig(const SynthRigOptions& options, const std::filesystem::path& out,
                               const std::atomic<bool>& stop);

}  // namespace wallar::eval
