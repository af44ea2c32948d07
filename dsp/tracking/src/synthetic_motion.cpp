// SPDX-License-Identifier: Apache-2.0
/// @file synthetic_motion.cpp
/// @brief Head motion differentiated exactly, exposure integration over render_room sub-frames,
/// and the IMU that rides on the head.
#include "wallar/dsp/tracking/synthetic_motion.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "wallar/core/hash.hpp"

namespace wallar::dsp {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

// ---------------------------------------------------------------------------------------------
// Second-order forward-mode differentiation: a value with its first and second time
// derivatives. Every trajectory term is written once in these, so its velocity and
// acceleration are exact (to rounding), never finite differences.
struct Jet {
  double v = 0.0, d = 0.0, dd = 0.0;
};
Jet constant(double c) { return {c, 0.0, 0.0}; }
Jet operator+(Jet a, Jet b) { return {a.v + b.v, a.d + b.d, a.dd + b.dd}; }
Jet operator-(Jet a, Jet b) { return {a.v - b.v, a.d - b.d, a.dd - b.dd}; }
Jet operator-(Jet a) { return {-a.v, -a.d, -a.dd}; }
Jet operator+(Jet a, double c) { return {a.v + c, a.d, a.dd}; }
Jet operator*(double s, Jet a) { return {s * a.v, s * a.d, s * a.dd}; }
Jet operator*(Jet a, Jet b) {
  return {a.v * b.v, a.d * b.v + a.v * b.d, a.dd * b.v + 2.0 * a.d * b.d + a.v * b.dd};
}
Jet sin(Jet a) {
  const double s = std::sin(a.v), c = std::cos(a.v);
  return {s, c * a.d, c * a.dd - s * a.d * a.d};
}
Jet cos(Jet a) {
  const double s = std::sin(a.v), c = std::cos(a.v);
  return {c, -s * a.d, -s * a.dd - c * a.d * a.d};
}
// d/dt atan2(y, x) = (x y' - y x') / (x^2 + y^2); the x' y' terms cancel in the numerator's
// derivative.
Jet atan2(Jet y, Jet x) {
  const double r2 = x.v * x.v + y.v * y.v;
  const double n = x.v * y.d - y.v * x.d;
  const double n_d = x.v * y.dd - y.v * x.dd;
  const double r2_d = 2.0 * (x.v * x.d + y.v * y.d);
  return {std::atan2(y.v, x.v), n / r2, (n_d * r2 - n * r2_d) / (r2 * r2)};
}

// A sinusoid of time: amplitude * sin(2 pi f tau + phase).
Jet wave(Jet tau, double amplitude, double f_hz, double phase) {
  return amplitude * sin(2.0 * kPi * f_hz * tau + phase);
}

// The quintic smooth step S(x) = 10x^3 - 15x^4 + 6x^5 of tau / ramp (0 before, 1 after; C2).
Jet envelope(Jet tau, double ramp_s) {
  const double x = tau.v / ramp_s;
  if (x <= 0.0) return constant(0.0);
  if (x >= 1.0) return constant(1.0);
  const double s = x * x * x * (10.0 + x * (-15.0 + 6.0 * x));
  const double s1 = 30.0 * x * x * (1.0 - x) * (1.0 - x) / ramp_s;
  const double s2 = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / (ramp_s * ramp_s);
  // Chain rule through tau (tau' = 1, tau'' = 0 for model time).
  return {s, s1 * tau.d, s1 * tau.dd + s2 * tau.d * tau.d};
}

// The integral of the envelope from 0 to tau: distance-like progress that starts at rest.
Jet envelope_integral(Jet tau, double ramp_s) {
  const double x = tau.v / ramp_s;
  if (x <= 0.0) return constant(0.0);
  const Jet e = envelope(tau, ramp_s);
  if (x >= 1.0) return {0.5 * ramp_s + (tau.v - ramp_s), tau.d, tau.dd};
  const double g = ramp_s * x * x * x * x * (2.5 + x * (-3.0 + x));
  return {g, e.v * tau.d, e.v * tau.dd + e.d * tau.d};
}

// A quick turn: yaw * (x - sin(2 pi x) / (2 pi)), x = (tau - start) / duration in [0, 1]; its
// rate yaw / duration * (1 - cos 2 pi x) peaks at 2 yaw / duration at mid-turn.
Jet turn_profile(Jet tau, const QuickTurn& turn) {
  const double x = (tau.v - turn.t_start_s) / turn.duration_s;
  if (x <= 0.0) return constant(0.0);
  if (x >= 1.0) return constant(turn.yaw_rad);
  const double D = turn.duration_s;
  const double w = 2.0 * kPi * x;
  const double p = x - std::sin(w) / (2.0 * kPi);
  const double p1 = (1.0 - std::cos(w)) / D;
  const double p2 = 2.0 * kPi * std::sin(w) / (D * D);
  return {turn.yaw_rad * p, turn.yaw_rad * p1 * tau.d,
          turn.yaw_rad * (p1 * tau.dd + p2 * tau.d * tau.d)};
}

/// The yaw the quick turns added by model time t: the turns before the last one that started
/// are complete (turns never overlap).
Jet quick_turn_yaw(const std::vector<QuickTurn>& turns, const std::vector<double>& yaw_before,
                   const Jet& t) {
  const auto it = std::upper_bound(turns.begin(), turns.end(), t.v,
                                   [](double x, const QuickTurn& q) { return x < q.t_start_s; });
  if (it == turns.begin()) return constant(0.0);
  const std::size_t i = static_cast<std::size_t>(it - turns.begin()) - 1;
  return turn_profile(t, turns[i]) + yaw_before[i];
}

using core::mix64;
double unit_open(std::uint64_t h) { return (static_cast<double>(h >> 11) + 0.5) * 0x1.0p-53; }

// Standard normal deviates from a std::mt19937_64 (whose output the standard fixes) by
// Box-Muller: the std:: distributions differ between standard libraries.
class Gaussian {
 public:
  explicit Gaussian(std::mt19937_64& rng) : rng_(rng) {}
  double operator()() {
    if (have_spare_) {
      have_spare_ = false;
      return spare_;
    }
    const double r = std::sqrt(-2.0 * std::log(unit_open(rng_())));
    const double a = 2.0 * kPi * unit_open(rng_());
    spare_ = r * std::sin(a);
    have_spare_ = true;
    return r * std::cos(a);
  }
  Eigen::Vector3d vec() {
    const double x = (*this)(), y = (*this)(), z = (*this)();
    return {x, y, z};
  }

 private:
  std::mt19937_64& rng_;
  bool have_spare_ = false;
  double spare_ = 0.0;
};

// Standard normal quantiles at the midpoints of 4096 equal-probability bins, scaled to unit
// variance: pixel noise takes 12 bits of a hash per deviate (five per 64-bit hash), which costs
// a table lookup instead of Box-Muller's logarithm and cosine per pair of pixels.
constexpr int kQuantileBits = 12;
const std::array<float, 1u << kQuantileBits>& normal_quantiles() {
  static const std::array<float, 1u << kQuantileBits> table = [] {
    std::array<double, 1u << kQuantileBits> z{};
    double sum2 = 0.0;
    for (std::size_t i = 0; i < z.size(); ++i) {
      const double p = (static_cast<double>(i) + 0.5) / static_cast<double>(z.size());
      double lo = -10.0, hi = 10.0;  // bisection on the normal CDF 0.5 erfc(-x / sqrt 2)
      for (int it = 0; it < 80; ++it) {
        const double mid = 0.5 * (lo + hi);
        (0.5 * std::erfc(-mid / std::numbers::sqrt2) < p ? lo : hi) = mid;
      }
      z[i] = 0.5 * (lo + hi);
      sum2 += z[i] * z[i];
    }
    const double scale = 1.0 / std::sqrt(sum2 / static_cast<double>(z.size()));
    std::array<float, 1u << kQuantileBits> out{};
    for (std::size_t i = 0; i < z.size(); ++i) out[i] = static_cast<float>(z[i] * scale);
    return out;
  }();
  return table;
}

// The head's joint: the IMU sits this far ahead of and above the neck's pivot (body frame), so
// turning the head moves the cameras too.
const Eigen::Vector3d kNeckToBody(0.08, 0.0, 0.11);
constexpr double kEyeHeightM = 1.65;  // standing, the IMU's height
constexpr double kStepLengthM = 0.7;
constexpr double kBobM = 0.025;               // vertical head bob per step
constexpr double kSwayM = 0.02;               // lateral sway per stride
constexpr double kPitchDownRad = 5.0 * kDeg;  // a head at rest looks slightly down

struct Room {
  double cx, cy, sx, sy, sz;
};
Room dims(const SyntheticRoom& r) {
  return {0.5 * (r.x_min_m + r.x_max_m), 0.5 * (r.y_min_m + r.y_max_m), r.x_max_m - r.x_min_m,
          r.y_max_m - r.y_min_m, r.z_max_m};
}

// Ellipse of the walking presets: speed variance over the lap for the phase correction eps
// (phi = theta + eps sin 2 theta), and the lap length.
double speed_variance(double a, double b, double eps, double* length = nullptr) {
  constexpr int kN = 720;
  double sum = 0.0, sum2 = 0.0;
  for (int i = 0; i < kN; ++i) {
    const double th = 2.0 * kPi * (i + 0.5) / kN;
    const double phi = th + eps * std::sin(2.0 * th);
    const double dphi = 1.0 + 2.0 * eps * std::cos(2.0 * th);
    const double s = std::hypot(a * std::sin(phi), b * std::cos(phi)) * dphi;  // |dr/dtheta|
    sum += s;
    sum2 += s * s;
  }
  if (length != nullptr) *length = sum * 2.0 * kPi / kN;
  const double mean = sum / kN;
  return sum2 / kN - mean * mean;
}

}  // namespace

std::string_view to_string(HeadMotion motion) {
  return kHeadMotionNames[static_cast<std::size_t>(motion)];
}

std::optional<HeadMotion> head_motion_named(std::string_view name) {
  for (std::size_t i = 0; i < kHeadMotionNames.size(); ++i) {
    if (kHeadMotionNames[i] == name) return static_cast<HeadMotion>(i);
  }
  return std::nullopt;
}

SyntheticRoom headset_room(std::uint64_t texture_seed) {
  SyntheticRoom room;
  room.x_min_m = -4.0;
  room.x_max_m = 4.0;
  room.y_min_m = -3.0;
  room.y_max_m = 3.0;
  room.z_max_m = 3.0;
  room.texture_seed = texture_seed;
  return room;
}

SyntheticRoom small_room(std::uint64_t texture_seed) {
  SyntheticRoom room;
  room.x_min_m = -2.0;
  room.x_max_m = 2.0;
  room.y_min_m = -2.5;
  room.y_max_m = 2.5;
  room.z_max_m = 2.5;
  room.texture_seed = texture_seed;
  return room;
}

HeadMotionModel::HeadMotionModel(const SyntheticRoom& room, const HeadMotionConfig& config)
    : room_(room), config_(config) {
  const Room r = dims(room);
  const bool walking = config.motion == HeadMotion::kWalk ||
                       config.motion == HeadMotion::kRoomLoop ||
                       config.motion == HeadMotion::kWalkTurns;
  const double need_x = walking ? 5.0 : 3.0, need_y = walking ? 4.0 : 3.0;
  if (!(r.sx >= need_x && r.sy >= need_y && r.sz >= 2.2)) {
    char what[96];
    std::snprintf(what, sizeof what,
                  "head motion '%s' needs a room of at least %.0f x %.0f x 2.2 m",
                  std::string(to_string(config.motion)).c_str(), need_x, need_y);
    throw std::invalid_argument(what);
  }
  if (!(config.still_start_s >= 0.0) || !(config.ramp_s > 0.0) || !(config.peak_turn_deg_s > 0.0) ||
      !(config.walk_speed_m_s > 0.0) || !(config.duration_s >= 0.0)) {
    throw std::invalid_argument(
        "head motion: needs still_start_s >= 0, ramp_s > 0, peak_turn_deg_s > 0, "
        "walk_speed_m_s > 0 and duration_s >= 0");
  }
  for (std::size_t i = 0; i < phase_.size(); ++i) {
    phase_[i] = 2.0 * kPi * unit_open(mix64(config.seed * 0x9E3779B97F4A7C15ULL + i + 1));
  }
  const double neck_z = std::min(kEyeHeightM, r.sz - 0.6) - kNeckToBody.z();
  stand_neck_world_ = Eigen::Vector3d(r.cx - 0.1 * r.sx, r.cy - 0.07 * r.sy, neck_z);
  stand_yaw_rad_ = phase_[7];
  if (walking) {
    Path& p = path_;
    p.cx = r.cx;
    p.cy = r.cy;
    p.a = 0.5 * r.sx - 1.6;
    p.b = 0.5 * r.sy - 1.3;
    // The phase correction that makes the speed along the ellipse nearly constant: golden
    // section on the speed variance (its first-order value is (a^2 - b^2) / (2 (a^2 + b^2))).
    double lo = -0.45, hi = 0.45;
    for (int it = 0; it < 80; ++it) {
      const double m1 = hi - (hi - lo) * 0.6180339887498949;
      const double m2 = lo + (hi - lo) * 0.6180339887498949;
      if (speed_variance(p.a, p.b, m1) < speed_variance(p.a, p.b, m2)) {
        hi = m2;
      } else {
        lo = m1;
      }
    }
    p.eps = 0.5 * (lo + hi);
    double length = 0.0;
    speed_variance(p.a, p.b, p.eps, &length);
    p.omega_rad_s = 2.0 * kPi * config.walk_speed_m_s / length;
    p.steps_per_lap = 2 * std::max(1, static_cast<int>(std::lround(length / (2.0 * kStepLengthM))));
  }
  if (config.motion == HeadMotion::kQuickTurns) {
    std::mt19937_64 rng(mix64(config.seed ^ 0x7175696B7475726EULL));
    const double peak = config.peak_turn_deg_s * kDeg;
    double t = config.still_start_s + config.ramp_s;
    double sum = 0.0;
    constexpr std::array<double, 3> kAmplitudesDeg = {60.0, 90.0, 120.0};
    while (t < config.duration_s + 5.0) {
      const double amplitude = kAmplitudesDeg[rng() % 3] * kDeg;
      double sign = (rng() & 1) != 0 ? 1.0 : -1.0;
      if (std::abs(sum + sign * amplitude) > 135.0 * kDeg) sign = -sign;
      QuickTurn turn{t, 2.0 * amplitude / peak, sign * amplitude};
      turns_.push_back(turn);
      turn_yaw_before_.push_back(sum);
      sum += turn.yaw_rad;
      t += turn.duration_s + 1.0 + 1.5 * unit_open(rng());
    }
  }
  if (config.motion == HeadMotion::kCalibration) {
    // Tilts held still, each turned round in quarter turns with a hold after each: every
    // start and stop is sharp (a turn's rate rises from 0 to its peak in a quarter of it).
    std::mt19937_64 rng(mix64(config.seed ^ 0x63616C6962ULL));
    constexpr double kPeakRad = 150.0 * kDeg;
    constexpr std::array<std::array<double, 2>, 6> kTiltsDeg = {
        {{0.0, 0.0}, {75.0, 0.0}, {-75.0, 0.0}, {0.0, 75.0}, {0.0, -75.0}, {0.0, 0.0}}};
    double t = config.still_start_s;
    double pitch = 0.0, roll = 0.0, yaw = 0.0;
    for (std::size_t k = 0; k < kTiltsDeg.size(); ++k) {
      const double dp = kTiltsDeg[k][0] * kDeg - pitch, dr = kTiltsDeg[k][1] * kDeg - roll;
      double tilt_s = 0.0;
      if (dp != 0.0) {
        pitch_turns_.push_back(QuickTurn{t, 2.0 * std::abs(dp) / kPeakRad, dp});
        pitch_before_.push_back(pitch);
        pitch += dp;
        tilt_s = pitch_turns_.back().duration_s;
      }
      if (dr != 0.0) {
        roll_turns_.push_back(QuickTurn{t, 2.0 * std::abs(dr) / kPeakRad, dr});
        roll_before_.push_back(roll);
        roll += dr;
        tilt_s = std::max(tilt_s, roll_turns_.back().duration_s);
      }
      t += tilt_s + 1.5 + 0.5 * unit_open(rng());
      if (k + 1 == kTiltsDeg.size()) break;  // back to level: done
      const double sign = k % 2 == 0 ? 1.0 : -1.0;
      for (int q = 0; q < 4; ++q) {
        const QuickTurn turn{t, 2.0 * (90.0 * kDeg) / kPeakRad, sign * 90.0 * kDeg};
        turns_.push_back(turn);
        turn_yaw_before_.push_back(yaw);
        yaw += turn.yaw_rad;
        t += turn.duration_s + 0.8 + 0.4 * unit_open(rng());
      }
    }
  }
  if (config.motion == HeadMotion::kWalkTurns) {
    // Glances: a quick turn aside, a look, the quick turn back, then walking on.
    std::mt19937_64 rng(mix64(config.seed ^ 0x77616C6B7475726EULL));
    const double peak = config.peak_turn_deg_s * kDeg;
    double t = config.still_start_s + config.ramp_s + 0.5;
    constexpr std::array<double, 3> kAmplitudesDeg = {60.0, 75.0, 90.0};
    while (t < config.duration_s + 5.0) {
      const double amplitude = kAmplitudesDeg[rng() % 3] * kDeg;
      const double sign = (rng() & 1) != 0 ? 1.0 : -1.0;
      for (const double yaw : {sign * amplitude, -sign * amplitude}) {
        QuickTurn turn{t, 2.0 * amplitude / peak, yaw};
        turn_yaw_before_.push_back(
            turns_.empty() ? 0.0 : turn_yaw_before_.back() + turns_.back().yaw_rad);
        turns_.push_back(turn);
        t += turn.duration_s + 0.4 + 0.6 * unit_open(rng());
      }
      t += 1.0 + 1.5 * unit_open(rng());
    }
  }
}

double HeadMotionModel::lap_period_s() const {
  return path_.omega_rad_s > 0.0 ? 2.0 * kPi / path_.omega_rad_s : 0.0;
}

BodyMotionState HeadMotionModel::state(double t_s) const {
  const Jet t{t_s, 1.0, 0.0};
  const Jet tau = t + (-config_.still_start_s);
  const Jet e = envelope(tau, config_.ramp_s);
  const auto& ph = phase_;
  std::array<Jet, 3> neck;
  Jet yaw, pitch, roll;
  switch (config_.motion) {
    case HeadMotion::kLookAround: {
      const Eigen::Vector3d& p0 = stand_neck_world_;
      neck = {e * wave(tau, 0.03, 0.23, ph[1]) + p0.x(), e * wave(tau, 0.025, 0.17, ph[2]) + p0.y(),
              e * wave(tau, 0.01, 0.29, ph[3]) + p0.z()};
      yaw = e * (wave(tau, 60.0 * kDeg, 0.06, ph[4]) + wave(tau, 20.0 * kDeg, 0.17, ph[5])) +
            stand_yaw_rad_;
      pitch = e * (wave(tau, 12.0 * kDeg, 0.09, ph[6]) + wave(tau, 4.0 * kDeg, 0.23, ph[0])) +
              kPitchDownRad;
      roll = e * wave(tau, 3.0 * kDeg, 0.11, ph[3] + 1.0);
      break;
    }
    case HeadMotion::kQuickTurns: {
      const Eigen::Vector3d& p0 = stand_neck_world_;
      neck = {e * wave(tau, 0.015, 0.2, ph[1]) + p0.x(), e * wave(tau, 0.015, 0.15, ph[2]) + p0.y(),
              e * wave(tau, 0.005, 0.25, ph[3]) + p0.z()};
      yaw = e * wave(tau, 6.0 * kDeg, 0.05, ph[4]) + quick_turn_yaw(turns_, turn_yaw_before_, t) +
            stand_yaw_rad_;
      pitch = e * wave(tau, 3.0 * kDeg, 0.07, ph[6]) + kPitchDownRad;
      roll = e * wave(tau, 1.0 * kDeg, 0.09, ph[0]);
      break;
    }
    case HeadMotion::kCalibration: {
      // Held in the hands at the standing head's place: only the scheduled turns move it.
      const Eigen::Vector3d& p0 = stand_neck_world_;
      neck = {constant(p0.x()), constant(p0.y()), constant(p0.z())};
      yaw = quick_turn_yaw(turns_, turn_yaw_before_, t) + stand_yaw_rad_;
      pitch = quick_turn_yaw(pitch_turns_, pitch_before_, t) + kPitchDownRad;
      roll = quick_turn_yaw(roll_turns_, roll_before_, t);
      break;
    }
    case HeadMotion::kWalk:
    case HeadMotion::kWalkTurns:
    case HeadMotion::kRoomLoop: {
      const Path& p = path_;
      const Jet theta = p.omega_rad_s * envelope_integral(tau, config_.ramp_s) + ph[7];
      const Jet phi = theta + p.eps * sin(2.0 * theta);
      const Jet heading = atan2(p.b * cos(phi), -p.a * sin(phi));  // the tangent, walking CCW
      const double steps = static_cast<double>(p.steps_per_lap);
      const Jet stride = sin(0.5 * steps * theta);  // one period per two steps
      const Jet lateral = e * (kSwayM * stride);
      neck = {p.a * cos(phi) + p.cx - lateral * sin(heading),
              p.b * sin(phi) + p.cy + lateral * cos(heading),
              e * (-kBobM * cos(steps * theta)) + (stand_neck_world_.z() - 0.5 * kBobM)};
      Jet look;
      if (config_.motion == HeadMotion::kWalk) {
        look = wave(tau, 25.0 * kDeg, 0.08, ph[1]) + wave(tau, 10.0 * kDeg, 0.21, ph[2]);
        pitch = e * wave(tau, 5.0 * kDeg, 0.13, ph[3]);
      } else if (config_.motion == HeadMotion::kWalkTurns) {
        look = wave(tau, 8.0 * kDeg, 0.08, ph[1]) + quick_turn_yaw(turns_, turn_yaw_before_, t);
        pitch = e * wave(tau, 4.0 * kDeg, 0.13, ph[3]);
      } else {  // every term a harmonic of the lap: the laps repeat
        look = 18.0 * kDeg * sin(2.0 * theta + ph[1]) + 8.0 * kDeg * sin(5.0 * theta + ph[2]);
        pitch = e * (4.0 * kDeg * sin(3.0 * theta + ph[3]));
      }
      yaw = heading + e * (look + 1.5 * kDeg * stride);
      pitch = pitch + e * (0.8 * kDeg * sin(steps * theta)) + kPitchDownRad;
      roll = e * (2.0 * kDeg * sin(0.5 * steps * theta + 0.5));
      break;
    }
  }
  // R_world_body = Rz(yaw) Ry(pitch) Rx(roll): body x forward, y left, z up; pitch > 0 looks
  // down.
  const Jet cy = cos(yaw), sy = sin(yaw), cp = cos(pitch), sp = sin(pitch), cr = cos(roll),
            sr = sin(roll);
  const std::array<std::array<Jet, 3>, 3> R = {{
      {cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr},
      {sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr},
      {-sp, cp * sr, cp * cr},
  }};
  BodyMotionState s;
  s.t_s = t_s;
  Eigen::Matrix3d Rv, Rd;
  for (int i = 0; i < 3; ++i) {
    Jet p = neck[static_cast<std::size_t>(i)];
    for (int j = 0; j < 3; ++j) {
      const Jet& rij = R[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)];
      Rv(i, j) = rij.v;
      Rd(i, j) = rij.d;
      p = p + kNeckToBody[j] * rij;
    }
    s.T_world_body.translation()[i] = p.v;
    s.vel_world_m_s[i] = p.d;
    s.accel_world_m_s2[i] = p.dd;
  }
  s.T_world_body.linear() = Rv;
  // [omega]x = R^T dR/dt (body frame); its antisymmetric part, exact to rounding.
  const Eigen::Matrix3d W = Rv.transpose() * Rd;
  s.omega_body_rad_s =
      0.5 * Eigen::Vector3d(W(2, 1) - W(1, 2), W(0, 2) - W(2, 0), W(1, 0) - W(0, 1));
  return s;
}

HeadsetRig default_headset_rig() {
  HeadsetRig rig;
  rig.camera.width_px = 640;
  rig.camera.height_px = 480;
  rig.camera.f_px = 450.0;
  rig.camera.cx_px = 319.5;
  rig.camera.cy_px = 239.5;
  rig.camera.baseline_m = 0.10;
  rig.camera.samples_per_axis = 2;
  // Camera axes in the body: x right = -y_body, y down = -z_body, z forward = x_body; then a
  // mounting error of 0.6, -0.8 and 0.4 degrees about the camera's axes (1.1 degrees in all).
  Eigen::Matrix3d R;
  R.col(0) = -Eigen::Vector3d::UnitY();
  R.col(1) = -Eigen::Vector3d::UnitZ();
  R.col(2) = Eigen::Vector3d::UnitX();
  R = R * Eigen::AngleAxisd(0.6 * kDeg, Eigen::Vector3d::UnitX()).toRotationMatrix() *
      Eigen::AngleAxisd(-0.8 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix() *
      Eigen::AngleAxisd(0.4 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  rig.T_body_cam0.linear() = R;
  rig.T_body_cam0.translation() = Eigen::Vector3d(0.02, 0.035, 0.01);
  rig.imu.gyro_noise_density = 2.6e-4;
  rig.imu.gyro_random_walk = 2.0e-5;
  rig.imu.accel_noise_density = 2.3e-3;
  rig.imu.accel_random_walk = 3.0e-4;
  return rig;
}

RigCalibration headset_rig_calibration(const HeadsetRig& rig, double camera_rate_hz,
                                       double imu_rate_hz) {
  RigCalibration out;
  for (std::size_t i = 0; i < 2; ++i) {
    CameraCalibration& c = out.cams[i];
    c.name = i == 0 ? "cam0" : "cam1";
    c.width_px = rig.camera.width_px;
    c.height_px = rig.camera.height_px;
    c.rate_hz = camera_rate_hz;
    c.fx = c.fy = rig.camera.f_px;
    c.cx = rig.camera.cx_px;
    c.cy = rig.camera.cy_px;
    c.distortion_model = "radial-tangential";
    c.distortion = {0.0, 0.0, 0.0, 0.0};
  }
  out.cams[0].T_body_cam = rig.T_body_cam0;
  out.cams[1].T_body_cam =
      rig.T_body_cam0 * Eigen::Translation3d(Eigen::Vector3d(rig.camera.baseline_m, 0.0, 0.0));
  out.imu = rig.imu;
  out.imu.rate_hz = imu_rate_hz;
  out.imu.T_body_imu = SE3d::Identity();
  return out;
}

// ---------------------------------------------------------------------------------------------
// Image formation

double row_time_s(const ImagingConfig& config, int height_px, double t_frame_s, int v) {
  if (height_px <= 1 || !(config.rolling_shutter_s > 0.0)) return t_frame_s;
  const double mid = 0.5 * static_cast<double>(height_px - 1);
  return t_frame_s + (static_cast<double>(v) - mid) * config.rolling_shutter_s /
                         static_cast<double>(height_px - 1);
}

double image_motion_px(const SyntheticRoom& room, const SyntheticCamera& camera,
                       const SE3d& T_world_cam_0, const SE3d& T_world_cam_1) {
  const double w = camera.width_px - 1, h = camera.height_px - 1;
  const std::array<Eigen::Vector2d, 9> probes = {
      Eigen::Vector2d(0, 0),     Eigen::Vector2d(w, 0),     Eigen::Vector2d(0, h),
      Eigen::Vector2d(w, h),     Eigen::Vector2d(w / 2, 0), Eigen::Vector2d(w / 2, h),
      Eigen::Vector2d(0, h / 2), Eigen::Vector2d(w, h / 2), Eigen::Vector2d(w / 2, h / 2)};
  const SE3d T_1_world = T_world_cam_1.inverse();
  double worst = 0.0;
  for (const Eigen::Vector2d& uv : probes) {
    const Eigen::Vector3d ray((uv.x() - camera.cx_px) / camera.f_px,
                              (uv.y() - camera.cy_px) / camera.f_px, 1.0);
    const auto hit = ray_hit(room, T_world_cam_0.translation(), T_world_cam_0.linear() * ray);
    if (!hit) continue;
    const Eigen::Vector3d p = T_1_world * hit->p_world;
    if (!(p.z() > 1e-6)) {
      worst = std::max(worst, 2.0 * camera.f_px);
      continue;
    }
    const Eigen::Vector2d uv1(camera.f_px * p.x() / p.z() + camera.cx_px,
                              camera.f_px * p.y() / p.z() + camera.cy_px);
    worst = std::max(worst, (uv1 - uv).norm());
  }
  return worst;
}

FrameFormation form_stereo_frame(const SyntheticRoom& room, const SyntheticCamera& camera,
                                 const CameraPoseFn& T_world_cam0_at, double t_frame_s, double gain,
                                 std::uint64_t frame_index, const ImagingConfig& config,
                                 std::span<std::uint8_t> left, std::span<std::uint8_t> right,
                                 std::vector<float>& scratch) {
  const std::size_t w = static_cast<std::size_t>(std::max(camera.width_px, 0));
  const std::size_t h = static_cast<std::size_t>(std::max(camera.height_px, 0));
  const std::size_t n = w * h;
  if (n == 0 || left.size() != n || right.size() != n) {
    throw std::invalid_argument("form_stereo_frame: outputs must hold width * height pixels");
  }
  if (!(config.exposure_s >= 0.0) || !(config.blur_step_px > 0.0) || config.max_blur_samples < 1 ||
      !(config.rolling_shutter_s >= 0.0) || !(config.read_noise_dn >= 0.0) ||
      !(config.shot_noise_dn >= 0.0) || !(gain > 0.0) || config.still_samples_per_axis < 1 ||
      config.still_samples_per_axis > 16) {
    throw std::invalid_argument("form_stereo_frame: bad imaging config or gain");
  }
  FrameFormation info;
  const bool blur = config.blur && config.exposure_s > 0.0;
  if (blur) {
    const double half = 0.5 * config.exposure_s;
    info.motion_px = image_motion_px(room, camera, T_world_cam0_at(t_frame_s - half),
                                     T_world_cam0_at(t_frame_s + half));
    info.blur_samples =
        std::clamp(static_cast<int>(std::ceil(info.motion_px / config.blur_step_px)), 1,
                   config.max_blur_samples);
  }
  SyntheticCamera cam = camera;
  cam.samples_per_axis = info.blur_samples == 1 ? config.still_samples_per_axis : 1;
  cam.adaptive = config.adaptive_supersampling;
  scratch.assign(2 * n, 0.0f);
  const std::span<float> acc0(scratch.data(), n), acc1(scratch.data() + n, n);
  const bool rolling = config.rolling_shutter_s > 0.0 && h > 1;
  std::vector<SE3d> poses(rolling ? h : 1);
  const float weight = 1.0f / static_cast<float>(info.blur_samples);
  for (int j = 0; j < info.blur_samples; ++j) {
    const double dt =
        blur ? ((j + 0.5) / info.blur_samples - 0.5) * config.exposure_s : 0.0;  // stratified
    for (std::size_t v = 0; v < poses.size(); ++v) {
      poses[v] = T_world_cam0_at(
          row_time_s(config, camera.height_px, t_frame_s, static_cast<int>(v)) + dt);
    }
    render_room_accumulate(room, cam, poses, 0, weight, acc0);
    render_room_accumulate(room, cam, poses, 1, weight, acc1);
  }
  if (config.optics_blur) {
    // The lens and the pixels' crosstalk: a separable [1 2 1] / 4 kernel (sigma 0.7 px), edges
    // clamped. It also smooths what is left of the sub-frames' steps in a motion streak.
    std::vector<float> row(w);
    for (const std::span<float> acc : {acc0, acc1}) {
      for (std::size_t v = 0; v < h; ++v) {
        float* p = acc.data() + v * w;
        std::copy(p, p + w, row.begin());
        for (std::size_t u = 0; u < w; ++u) {
          const float l = row[u > 0 ? u - 1 : 0], r = row[u + 1 < w ? u + 1 : w - 1];
          p[u] = 0.25f * (l + r) + 0.5f * row[u];
        }
      }
      std::vector<float> above(acc.begin(), acc.begin() + static_cast<std::ptrdiff_t>(w));
      for (std::size_t v = 0; v < h; ++v) {
        float* p = acc.data() + v * w;
        const float* below = acc.data() + (v + 1 < h ? v + 1 : v) * w;
        for (std::size_t u = 0; u < w; ++u) {
          const float centre = p[u];
          p[u] = 0.25f * (above[u] + below[u]) + 0.5f * centre;
          above[u] = centre;
        }
      }
    }
  }
  const bool noisy = config.read_noise_dn > 0.0 || config.shot_noise_dn > 0.0;
  const double read_var = config.read_noise_dn * config.read_noise_dn;
  const double shot = config.shot_noise_dn * gain;
  for (int c = 0; c < 2; ++c) {
    const std::span<float> acc = c == 0 ? acc0 : acc1;
    const std::span<std::uint8_t> out = c == 0 ? left : right;
    const std::uint64_t key = mix64(mix64(config.seed ^ 0x696D616765ULL) ^
                                    mix64(frame_index * 2 + static_cast<std::uint64_t>(c)));
    const auto& quantile = normal_quantiles();
    constexpr std::size_t kPerHash = 64 / kQuantileBits;
    constexpr std::uint64_t kMask = (1u << kQuantileBits) - 1;
    for (std::size_t i = 0; i < n; i += kPerHash) {
      // Counter-based: the deviates of pixels i..i+4 come from one hash of (key, i).
      std::uint64_t bits = noisy ? mix64(key ^ (i * 0xD1B54A32D192ED03ULL)) : 0;
      for (std::size_t k = i; k < std::min(n, i + kPerHash); ++k, bits >>= kQuantileBits) {
        const double signal = gain * static_cast<double>(acc[k]);
        double value = signal;
        if (noisy) {
          value += std::sqrt(read_var + shot * std::max(signal, 0.0)) *
                   static_cast<double>(quantile[bits & kMask]);
        }
        out[k] = static_cast<std::uint8_t>(std::clamp(value, 0.0, 255.0) + 0.5);
      }
    }
  }
  return info;
}

std::vector<double> auto_exposure_gains(std::size_t frames, double camera_rate_hz, bool enabled,
                                        std::uint64_t seed, double step) {
  std::vector<double> gains(frames, 1.0);
  if (!enabled || frames == 0) return gains;
  if (!(camera_rate_hz > 0.0) || !(step > 1.0)) {
    throw std::invalid_argument("auto_exposure_gains: needs a rate > 0 and a step > 1");
  }
  std::mt19937_64 rng(mix64(seed ^ 0x6761696E73ULL));
  int level = 0;
  auto next_change = [&](std::size_t from) {
    return from + std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(
                                               (2.0 + 3.0 * unit_open(rng())) * camera_rate_hz)));
  };
  std::size_t change = next_change(0);
  for (std::size_t k = 0; k < frames; ++k) {
    if (k == change) {
      const bool up = level <= -2 ? true : level >= 2 ? false : (rng() & 1) != 0;
      level += up ? 1 : -1;
      change = next_change(k);
    }
    gains[k] = std::pow(step, level);
  }
  return gains;
}

// ---------------------------------------------------------------------------------------------
// IMU

void draw_initial_biases(SyntheticImuConfig& config, std::uint64_t seed) {
  std::mt19937_64 rng(mix64(seed ^ 0x62696173ULL));
  Gaussian g(rng);
  config.gyro_bias0_rad_s = 0.005 * g.vec();
  config.accel_bias0_m_s2 = 0.05 * g.vec();
}

void draw_magnetometer_iron(SyntheticImuConfig& config, std::uint64_t seed) {
  std::mt19937_64 rng(mix64(seed ^ 0x69726F6EULL));
  Gaussian g(rng);
  config.mag.enabled = true;
  config.mag.hard_iron_uT = 20.0 * g.vec();
  Eigen::Matrix3d e;
  for (int i = 0; i < 3; ++i) {
    for (int j = i; j < 3; ++j) e(i, j) = e(j, i) = 0.05 * g();
  }
  config.mag.soft_iron = Eigen::Matrix3d::Identity() + e;
}

SyntheticImu::SyntheticImu(const HeadMotionModel& model, const SyntheticImuConfig& config,
                           TimeNs t0_ns, TimeNs first_ns)
    : model_(model),
      config_(config),
      t0_ns_(t0_ns),
      first_ns_(first_ns),
      bg_(config.gyro_bias0_rad_s),
      ba_(config.accel_bias0_m_s2),
      rng_(mix64(config.seed ^ 0x696D7530ULL)),
      mag_rng_(mix64(config.seed ^ 0x6D616730ULL)) {
  const ImuCalibration& n = config.noise;
  if (!(config.rate_hz >= 1.0 && config.rate_hz <= 10000.0)) {
    throw std::invalid_argument("SyntheticImu: rate must be 1-10000 Hz");
  }
  if (!(n.gyro_noise_density >= 0.0 && n.gyro_random_walk >= 0.0 && n.accel_noise_density >= 0.0 &&
        n.accel_random_walk >= 0.0)) {
    throw std::invalid_argument("SyntheticImu: noise densities must be >= 0");
  }
}

TimeNs SyntheticImu::next_truth_t_ns() const {
  return first_ns_ +
         static_cast<TimeNs>(std::llround(static_cast<double>(k_) * 1e9 / config_.rate_hz));
}

SyntheticImuRow SyntheticImu::next() {
  SyntheticImuRow row;
  row.truth_t_ns = next_truth_t_ns();
  row.truth = model_.state(static_cast<double>(row.truth_t_ns - t0_ns_) * 1e-9);
  row.gyro_bias_rad_s = bg_;
  row.accel_bias_m_s2 = ba_;
  const ImuCalibration& n = config_.noise;
  const double sqrt_rate = std::sqrt(config_.rate_hz);
  Gaussian g(rng_);
  const Eigen::Vector3d gravity_world(0.0, 0.0, -config_.gravity_m_s2);
  row.sample.t_ns = row.truth_t_ns + config_.clock_offset_ns;
  row.sample.gyro_rad_s =
      row.truth.omega_body_rad_s + bg_ + n.gyro_noise_density * sqrt_rate * g.vec();
  row.sample.accel_m_s2 =
      row.truth.T_world_body.linear().transpose() * (row.truth.accel_world_m_s2 - gravity_world) +
      ba_ + n.accel_noise_density * sqrt_rate * g.vec();
  bg_ += n.gyro_random_walk / sqrt_rate * g.vec();
  ba_ += n.accel_random_walk / sqrt_rate * g.vec();
  const SyntheticMagnetometerConfig& mag = config_.mag;
  if (mag.enabled && k_ % static_cast<std::uint64_t>(std::max(1, mag.every_n_samples)) == 0) {
    Gaussian gm(mag_rng_);
    row.sample.mag_uT =
        mag.soft_iron * (row.truth.T_world_body.linear().transpose() * mag.field_world_uT) +
        mag.hard_iron_uT + mag.noise_uT * gm.vec();
  }
  ++k_;
  return row;
}

}  // namespace wallar::dsp
