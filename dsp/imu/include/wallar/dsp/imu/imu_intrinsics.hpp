// SPDX-License-Identifier: Apache-2.0
/// @file imu_intrinsics.hpp
/// @brief The accelerometer's bias from still poses in several tilts, and the magnetometer's
/// hard and soft iron from an ellipsoid fit over a turning recording: what `wallar calibrate
/// accel-mag` runs.
///
/// Accelerometer: held still, it reads a = R_body_world * (0, 0, g) + b. Over poses whose "up"
/// directions span the three axes, |a_i - b| = g pins the bias b (Gauss-Newton from b = 0). A
/// bias alone needs tilts that span 3-D (level, a few tens of degrees forward, back, left and
/// right); PX4's six sides also give scale factors, which this does not estimate.
///
/// Magnetometer: in a clean field f (|f| = B) the readings lie on an ellipsoid,
/// m = S^-1 f + h: h the hard iron (fields of magnetised parts turning with the headset), S the
/// soft iron (parts that bend the field). The quadric through the readings is fitted by linear
/// least squares in 9 coefficients (on centred, scaled data), its centre is h and its shape
/// gives S as the symmetric square root; Gauss-Newton on |S (m - h)| - B then refines all
/// nine. S is defined up to a rotation by the readings alone: the symmetric root is the
/// convention (as in PX4, Ellipsoid-fit calibrations of ST and NXP application notes).
///
/// Threading: pure functions; no state.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <vector>

#include "wallar/core/imu_sample.hpp"

namespace wallar::dsp {

/// What counts as holding still, and how still windows join into poses.
struct StillPoseParams {
  DurationNs window_ns = 250 * kNsPerMs;  //!< the samples are cut into windows this long
  double max_gyro_mean_rad_s = 0.05;      //!< a slow steady turn is not still (bias ~0.01)
  double max_gyro_std_rad_s = 0.03;
  double max_accel_std_m_s2 = 0.15;
  /// Consecutive still windows whose "up" differs by less than this are one pose [deg].
  double merge_angle_deg = 2.0;
  DurationNs min_pose_ns = 500 * kNsPerMs;  //!< shorter holds are not used
};

/// One held pose: the mean accelerometer reading over its still windows.
struct StillPose {
  TimeNs t_begin_ns = 0;
  TimeNs t_end_ns = 0;
  std::size_t samples = 0;
  Eigen::Vector3d mean_accel_m_s2 = Eigen::Vector3d::Zero();
};

/// The poses held still in `samples` (increasing t_ns), in time order.
[[nodiscard]] std::vector<StillPose> find_still_poses(std::span<const ImuSample> samples,
                                                      const StillPoseParams& params = {});

struct AccelBiasFit {
  bool solved = false;
  Eigen::Vector3d bias_m_s2 = Eigen::Vector3d::Zero();
  std::size_t poses = 0;
  double residual_rms_m_s2 = 0.0;  //!< of |a_i - b| - g over the poses
  /// Smallest eigenvalue of the mean of u u^T over the poses' unit "up" directions u: 1/3 for
  /// directions spread evenly over the sphere, 0 when the poses never tilt about some axis
  /// (then that part of the bias is not observable).
  double direction_spread = 0.0;
};

/// Least spread accepted by fit_accel_bias (about +-20 degree tilts in both directions).
inline constexpr double kMinAccelDirectionSpread = 0.03;

/// The bias that puts every pose's reading at `gravity_m_s2` from it. Not solved with fewer
/// than 4 poses or a direction_spread below kMinAccelDirectionSpread.
[[nodiscard]] AccelBiasFit fit_accel_bias(std::span<const Eigen::Vector3d> pose_means_m_s2,
                                          double gravity_m_s2);

struct MagnetometerFit {
  bool solved = false;
  Eigen::Vector3d hard_iron_uT = Eigen::Vector3d::Zero();
  Eigen::Matrix3d soft_iron = Eigen::Matrix3d::Identity();  //!< field = S (m - h)
  double field_uT = 0.0;                                    //!< B: |S (m - h)| on average
  std::size_t samples = 0;
  double residual_rms_uT = 0.0;  //!< of |S (m - h)| - B
  /// Smallest eigenvalue of the covariance of the corrected field's unit directions: 1/3 for
  /// readings all over the sphere, near 0 for turns about one axis only (a degenerate fit).
  double coverage = 0.0;
};

/// Least coverage accepted by fit_magnetometer.
inline constexpr double kMinMagCoverage = 0.06;

/// Fits the ellipsoid to the readings (at least 50). field_uT > 0 scales S so that the
/// corrected field has that magnitude (the local field strength); 0 keeps the sensor's own
/// scale (det S = 1). Not solved when the quadric is no ellipsoid or the coverage is below
/// kMinMagCoverage.
[[nodiscard]] MagnetometerFit fit_magnetometer(std::span<const Eigen::Vector3d> readings_uT,
                                               double field_uT = 0.0);

/// The heading of a body-frame magnetic field seen through R_world_body (z up): the angle of
/// its horizontal part from world x, counter-clockwise [rad].
[[nodiscard]] double field_heading_rad(const Eigen::Matrix3d& R_world_body,
                                       const Eigen::Vector3d& field_body);

}  // namespace wallar::dsp
