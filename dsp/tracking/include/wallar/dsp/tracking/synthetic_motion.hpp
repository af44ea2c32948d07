// SPDX-License-Identifier: Apache-2.0
/// @file synthetic_motion.hpp
/// @brief A moving headset in the synthetic room: head motion as people move in AR, the images
/// its stereo cameras would take (motion blur, rolling shutter, auto-exposure gain, noise) and
/// the IMU it carries (white noise and bias random walk from EuRoC-style densities, a clock
/// offset). Pure computation behind `wallar eval synth-rig`, which writes it as a recording.
///
/// Frames: world z up (gravity along -z), floor at z = 0 (SyntheticRoom). Body = the IMU frame,
/// x forward, y left, z up when the head is level. The cameras hang off the body through
/// HeadsetRig::T_body_cam0 (camera x right, y down, z forward); cam1 sits baseline_m along
/// cam0's +x with cam0's orientation (the rectified pair render_room draws).
///
/// The trajectory is a smooth function of continuous time, built from sinusoids, smooth steps
/// and an ellipse whose every term is differentiated exactly (second-order forward-mode
/// differentiation), so velocity, acceleration and angular rate are the derivatives of the pose
/// to rounding: the IMU is consistent with the ground truth by construction, and the tests
/// check it by integrating the IMU back.
///
/// Time: model time t_s is seconds from the clip's start (0 = the first camera frame). Every
/// preset stands still for HeadMotionConfig::still_start_s (an IMU still window), then fades
/// its motion in over ramp_s.
///
/// Threading: value types and const member functions; instances may be shared by threads
/// (nothing is mutable). SyntheticImu is used by one thread.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <span>
#include <string_view>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/core/imu_sample.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"
#include "wallar/dsp/tracking/synthetic_room.hpp"

namespace wallar::dsp {

/// Head-motion scenarios.
enum class HeadMotion {
  kLookAround,  //!< standing, looking around (yaw swings of about +-80 deg, up to ~45 deg/s)
  kWalk,        //!< walking an ellipse at walk_speed_m_s while looking around (not periodic)
  kQuickTurns,  //!< standing, quick head turns of 60-120 deg peaking at peak_turn_deg_s
  kRoomLoop,    //!< walking laps of one ellipse, every lap the same (map-capacity tests)
  kWalkTurns,   //!< walking while glancing aside: quick turns of 60-90 deg out and back
  /// Standing, the headset held in the hands: held still level and tilted about 45 deg forward,
  /// back, left and right, at each tilt turned round in four quarter turns with a hold after
  /// each (sharp starts and stops, about every axis): the motion for calibrating the
  /// accelerometer's bias, the magnetometer's iron and the camera-IMU time offset.
  kCalibration,
};
inline constexpr std::array<std::string_view, 6> kHeadMotionNames{
    "look-around", "walk", "quick-turns", "room-loop", "walk-turns", "calibration"};
[[nodiscard]] std::string_view to_string(HeadMotion motion);
[[nodiscard]] std::optional<HeadMotion> head_motion_named(std::string_view name);

struct HeadMotionConfig {
  HeadMotion motion = HeadMotion::kLookAround;
  std::uint64_t seed = 1;          //!< phases of the sinusoids, the quick turns' schedule
  double still_start_s = 1.0;      //!< at rest from t = -inf to here
  double ramp_s = 1.5;             //!< then the motion fades in (quintic smooth step) over this
  double peak_turn_deg_s = 300.0;  //!< quick-turns, walk-turns: peak angular rate of every turn
  double walk_speed_m_s = 1.25;    //!< walk, room-loop: speed along the path once ramped up
  /// quick-turns: the turn schedule is drawn up to this model time (later: the last pose holds
  /// apart from the slow sway).
  double duration_s = 60.0;
};

/// The body (IMU) frame's kinematic state at one time, world frame.
struct BodyMotionState {
  double t_s = 0.0;
  SE3d T_world_body = SE3d::Identity();
  Eigen::Vector3d vel_world_m_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_world_m_s2 = Eigen::Vector3d::Zero();  //!< d2p/dt2 (no gravity)
  Eigen::Vector3d omega_body_rad_s = Eigen::Vector3d::Zero();  //!< angular rate, body frame
};

/// One scheduled quick turn (yaw about world z), model time.
struct QuickTurn {
  double t_start_s = 0.0;
  double duration_s = 0.0;
  double yaw_rad = 0.0;  //!< signed amplitude; the peak rate 2|yaw|/duration is at mid-turn
};

/// The head-motion trajectory of one scenario in one room.
class HeadMotionModel {
 public:
  /// Throws std::invalid_argument for a room too small for the scenario (walking presets need
  /// 5 x 4 m, standing ones 3 x 3 m, all 2.2 m height), a non-positive speed or peak rate, or
  /// negative still/ramp times.
  HeadMotionModel(const SyntheticRoom& room, const HeadMotionConfig& config);

  [[nodiscard]] BodyMotionState state(double t_s) const;
  [[nodiscard]] SE3d T_world_body(double t_s) const { return state(t_s).T_world_body; }

  [[nodiscard]] const HeadMotionConfig& config() const { return config_; }
  [[nodiscard]] const SyntheticRoom& room() const { return room_; }
  /// quick-turns, walk-turns, calibration: the yaw turns; empty for the other scenarios.
  [[nodiscard]] const std::vector<QuickTurn>& turns() const { return turns_; }
  /// walk, room-loop: the time of one lap once at speed [s]; 0 for standing scenarios.
  [[nodiscard]] double lap_period_s() const;

  struct Path {  // walk, room-loop: the ellipse the neck walks
    double cx = 0, cy = 0, a = 0, b = 0, eps = 0, omega_rad_s = 0;
    int steps_per_lap = 0;
  };
  [[nodiscard]] const Path& path() const { return path_; }

 private:
  SyntheticRoom room_;
  HeadMotionConfig config_;
  std::array<double, 8> phase_{};  //!< seeded phases [rad]
  std::vector<QuickTurn> turns_;
  std::vector<double> turn_yaw_before_;  //!< summed yaw of the turns before turns_[i]
  /// calibration: the tilts, as turns of pitch and of roll (QuickTurn::yaw_rad their angle).
  std::vector<QuickTurn> pitch_turns_, roll_turns_;
  std::vector<double> pitch_before_, roll_before_;
  Path path_;
  Eigen::Vector3d stand_neck_world_ = Eigen::Vector3d::Zero();
  double stand_yaw_rad_ = 0.0;
};

/// An 8 x 6 x 3 m room centred on the origin: room enough to walk laps in.
[[nodiscard]] SyntheticRoom headset_room(std::uint64_t texture_seed = 1);
/// A 4 x 5 x 2.5 m room whose walls are 2-3 m from synthetic_trajectory's path (an EuRoC-like
/// rig's view): the tracker's tests and `wallar bench`'s synthetic sequence.
[[nodiscard]] SyntheticRoom small_room(std::uint64_t texture_seed = 1);

/// The headset: the rectified stereo pair render_room draws, where it sits on the IMU, and the
/// IMU's noise densities (EuRoC sensor.yaml: continuous-time densities; the discrete white noise
/// of one sample is density * sqrt(rate), the bias step density * sqrt(1 / rate)).
struct HeadsetRig {
  SyntheticCamera camera;
  /// cam0 in the body (IMU) frame: 2 cm ahead, 3.5 cm left, 1 cm above the IMU, looking along
  /// body x and turned by 1.1 degrees (a mounting error) so T_cam_imu is not an axis
  /// permutation.
  SE3d T_body_cam0 = SE3d::Identity();
  ImuCalibration imu;  //!< noise densities, T_body_imu identity, rate_hz
};
/// A 640 x 480, f = 450 px, 0.10 m baseline headset with a consumer MEMS IMU (ICM-20948-like:
/// gyro 2.6e-4 rad/s/sqrt(Hz), bias walk 2.0e-5; accel 2.3e-3 m/s^2/sqrt(Hz), bias walk 3.0e-4).
[[nodiscard]] HeadsetRig default_headset_rig();
/// The rig as a calibration (body = IMU): what the recording's sensor.yaml files hold.
[[nodiscard]] RigCalibration headset_rig_calibration(const HeadsetRig& rig, double camera_rate_hz,
                                                     double imu_rate_hz);

// ---------------------------------------------------------------------------------------------
// Image formation

struct ImagingConfig {
  double exposure_s = 0.005;  //!< the shutter is open this long around each row's time
  bool blur = true;           //!< integrate over the exposure (false: one instant per frame)
  /// Sub-frames are added until consecutive ones move at most this far in the image [px];
  /// after optics_blur and the pixel noise, steps of 2 px read as a continuous streak.
  double blur_step_px = 2.0;
  int max_blur_samples = 10;
  /// Rolling shutter: the time from the first row's exposure to the last's [s]; 0 = global.
  double rolling_shutter_s = 0.0;
  /// Supersampling (render_room's samples_per_axis) of a frame made of one sub-frame; frames of
  /// several sub-frames use 1 (the sub-frames' offsets along the motion do the anti-aliasing).
  int still_samples_per_axis = 2;
  bool adaptive_supersampling = true;  //!< SyntheticCamera::adaptive for those frames
  /// The optics' point spread: a [1 2 1] / 4 kernel along rows and columns (sigma 0.7 px).
  bool optics_blur = true;
  double read_noise_dn = 1.5;  //!< Gaussian read noise sigma [gray levels]; 0 = noise-free
  /// Shot noise: variance of gain_dn_per_e * signal [DN^2 per DN of signal] at unity gain, scaled
  /// by the gain (a higher analogue gain amplifies fewer electrons). 0 = none.
  double shot_noise_dn = 1.0 / 64.0;
  std::uint64_t seed = 1;  //!< pixel noise
};

/// What forming one frame did.
struct FrameFormation {
  int blur_samples = 1;    //!< sub-frames averaged
  double motion_px = 0.0;  //!< largest image motion of 9 probe pixels during the exposure
};

/// T_world_cam0 at model time t_s (the left camera's pose).
using CameraPoseFn = std::function<SE3d(double t_s)>;

/// The image time of row v of a frame stamped t_frame_s: rows are read top to bottom during
/// rolling_shutter_s and the frame's stamp is the middle row's (v = (height - 1) / 2) mid-exposure.
[[nodiscard]] double row_time_s(const ImagingConfig& config, int height_px, double t_frame_s,
                                int v);

/// The largest motion of 9 probe pixels (corners, edge centres, centre) between the poses at
/// t0_s and t1_s [px]: the rays hit the room seen from the first pose and are re-projected
/// into the second (points behind the camera count as 2 * f).
[[nodiscard]] double image_motion_px(const SyntheticRoom& room, const SyntheticCamera& camera,
                                     const SE3d& T_world_cam_0, const SE3d& T_world_cam_1);

/// Forms the left (cam 0) and right (cam 1) image of the frame stamped t_frame_s: each is the
/// mean of N sub-frames taken at stratified times across each row's exposure window (N from the
/// image motion during the exposure, blur_step_px and max_blur_samples; 1 without blur; a
/// frame of one sub-frame is supersampled), through the optics' blur, times `gain`, plus read
/// and shot noise, clipped to 0-255 and rounded. Noise depends on (seed,
/// frame_index, cam, pixel) only. `scratch` is resized as needed (reuse it across frames).
/// Throws std::invalid_argument for outputs of the wrong size or a bad config.
FrameFormation form_stereo_frame(const SyntheticRoom& room, const SyntheticCamera& camera,
                                 const CameraPoseFn& T_world_cam0_at, double t_frame_s, double gain,
                                 std::uint64_t frame_index, const ImagingConfig& config,
                                 std::span<std::uint8_t> left, std::span<std::uint8_t> right,
                                 std::vector<float>& scratch);

/// Auto-exposure gain per frame: 1.0, then a multiplicative step of `step` up or down (kept
/// within step^-2 .. step^2) after every 2-5 s (seeded), changing between two frames. All 1.0
/// when not enabled.
[[nodiscard]] std::vector<double> auto_exposure_gains(std::size_t frames, double camera_rate_hz,
                                                      bool enabled, std::uint64_t seed,
                                                      double step = 1.25);

// ---------------------------------------------------------------------------------------------
// IMU

/// A magnetometer on the IMU: it reads m = soft_iron * (R_body_world * field_world) +
/// hard_iron + noise (so `soft_iron^-1` is what a calibration's S should find, up to scale).
struct SyntheticMagnetometerConfig {
  bool enabled = false;
  /// The earth's field in the world frame: 20 uT horizontal along world x, 43 uT down
  /// (inclination 65 deg, central Europe).
  Eigen::Vector3d field_world_uT{20.0, 0.0, -43.0};
  Eigen::Vector3d hard_iron_uT = Eigen::Vector3d::Zero();
  Eigen::Matrix3d soft_iron = Eigen::Matrix3d::Identity();
  double noise_uT = 0.3;    //!< white noise per axis and reading (AK09916: 0.15 uT LSB)
  int every_n_samples = 2;  //!< a reading with every n-th IMU sample (100 Hz at 200 Hz)
};

struct SyntheticImuConfig {
  double rate_hz = 200.0;
  /// The noise: gyro/accel noise densities and random walks (EuRoC units). All 0: a perfect IMU.
  ImuCalibration noise;
  Eigen::Vector3d gyro_bias0_rad_s = Eigen::Vector3d::Zero();  //!< bias at the first sample
  Eigen::Vector3d accel_bias0_m_s2 = Eigen::Vector3d::Zero();
  double gravity_m_s2 = 9.81;  //!< along world -z
  /// The IMU's clock runs this far ahead of the cameras' (and the ground truth's): a sample
  /// taken at true time t is stamped t + offset. Kalibr's timeshift_cam_imu (t_imu = t_cam +
  /// shift) is this offset.
  DurationNs clock_offset_ns = 0;
  std::uint64_t seed = 1;
  SyntheticMagnetometerConfig mag;  //!< off by default
};

/// Turn-on biases drawn from `seed` (gyro sigma 0.005 rad/s, accel 0.05 m/s^2 per axis).
void draw_initial_biases(SyntheticImuConfig& config, std::uint64_t seed);
/// Enables the magnetometer with hard iron (sigma 20 uT per axis) and soft iron (identity plus a
/// symmetric perturbation, sigma 0.05 per entry) drawn from `seed`.
void draw_magnetometer_iron(SyntheticImuConfig& config, std::uint64_t seed);

/// One synthesised IMU sample and the truth behind it.
struct SyntheticImuRow {
  ImuSample sample;       //!< t_ns on the IMU's clock (truth_t_ns + clock_offset_ns)
  TimeNs truth_t_ns = 0;  //!< when it was taken, on the cameras' clock
  BodyMotionState truth;
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();  //!< biases inside `sample`
  Eigen::Vector3d accel_bias_m_s2 = Eigen::Vector3d::Zero();
};

/// The IMU's samples one after another: sample k is taken at true time first_ns + k / rate (ns
/// rounded), gyro = omega_body + b_g + n_g, accel = R_world_body^T (a_world - g_world) + b_a +
/// n_a, with n ~ N(0, (density * sqrt(rate))^2) per axis and biases walking by
/// N(0, random_walk^2 / rate) per sample.
class SyntheticImu {
 public:
  /// t0_ns: the recording time of model time 0; `model` must outlive this. Throws
  /// std::invalid_argument for a rate outside 1-10000 Hz or negative densities.
  SyntheticImu(const HeadMotionModel& model, const SyntheticImuConfig& config, TimeNs t0_ns,
               TimeNs first_ns);

  [[nodiscard]] SyntheticImuRow next();
  [[nodiscard]] std::uint64_t index() const { return k_; }
  [[nodiscard]] TimeNs next_truth_t_ns() const;

 private:
  const HeadMotionModel& model_;
  SyntheticImuConfig config_;
  TimeNs t0_ns_, first_ns_;
  std::uint64_t k_ = 0;
  Eigen::Vector3d bg_, ba_;
  std::mt19937_64 rng_;
  std::mt19937_64 mag_rng_;  //!< its own stream: the IMU's noise is the same with or without
};

}  // namespace wallar::dsp
