// SPDX-License-Identifier: Apache-2.0
/// @file tracker.hpp
/// @brief The stereo PTAM-style tracker (thesis §2.1): the fixed-rate half of tracking and
/// mapping. Each stereo frame is rectified, then tracked in two stages:
///   1. the map points tracked in the last frame are projected with the predicted pose (gyro
///      rotation when given, else constant velocity), followed by pyramidal Lucas-Kanade, matched
///      along the rectified row in the right image, and the pose is found by RANSAC over
///      three-point stereo alignments and a Huber Gauss-Newton; reprojection outliers are dropped;
///   2. when too few points are tracked, map points in view that were not tracked are searched by
///      their 8x8 patches around their projection, and the pose is refined again with them.
/// A key-frame is made when the pose is far from every key-frame (distance relative to the
/// scene depth, or angle) or when too few points are tracked; it adds new map points from
/// bucketed corners matched along the rows, and is handed to the mapper (mapper.hpp) through
/// pending_keyframe(). The mapper's bundle adjustment comes back through apply().
/// When the pose cannot be found the state is kLost, the pose is carried on by the motion model
/// for a few frames, and each frame tries to relocalise: the key-frames whose thumbnails are most
/// like the frame are tried by appearance (the frame's corners matched to their points' binary
/// descriptors, then RANSAC) and by their points' patches around their poses. When that keeps
/// failing a new map segment starts at the predicted pose, so the output stays continuous.
///
/// Map points are named by (id, generation): an id freed by a cull is reused with the next
/// generation, and corrections or culls naming an older generation are ignored, so a message
/// about a point that no longer exists can never land on its successor.
///
/// Storage: every per-frame buffer, the map points and the key-frame records live in fixed
/// capacity storage sized by TrackerConfig at construction. track() and apply() allocate nothing.
///
/// Threading: one thread owns a Tracker (track(), apply(), the accessors). pending_keyframe()
/// is valid until the next track() on that thread.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>

#include "wallar/core/calibration.hpp"
#include "wallar/core/image.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"
#include "wallar/dsp/tracking/accel_prediction.hpp"
#include "wallar/dsp/tracking/features.hpp"
#include "wallar/dsp/tracking/fixed_vector.hpp"
#include "wallar/dsp/tracking/gray_image.hpp"
#include "wallar/dsp/tracking/klt.hpp"
#include "wallar/dsp/tracking/pose_estimation.hpp"
#include "wallar/dsp/tracking/stereo_camera.hpp"

namespace wallar::dsp {

enum class TrackingState : std::uint8_t {
  kInitialising,  //!< no map yet (too few stereo features so far)
  kTracking,
  kLost,  //!< the pose could not be found; relocalising
};
const char* to_string(TrackingState state);

struct TrackerConfig {
  int max_tracks = 300;       //!< features tracked per frame
  int keyframe_points = 800;  //!< new map points a key-frame may add (tracked while room)
  int max_map_points = 20000;
  int max_keyframes = 128;  //!< key-frame records kept (a ring) for relocalisation
  int pyramid_levels = 3;
  double min_depth_m = 0.25, max_depth_m = 20.0;
  /// Beyond max_depth_m, points up to this depth are made only when a key-frame finds too few
  /// nearer ones (a street ahead of a car, a far wall): they keep the pose, mostly its rotation,
  /// where near structure is missing. 0: the depth of a 4 px disparity.
  double far_depth_m = 0.0;
  /// A key-frame that leaves fewer than this share of max_tracks tracked with near points adds
  /// far ones (their bearings weighted by (max_depth_m / depth)^2 in the pose).
  double min_near_share = 0.45;
  /// A key-frame once the camera is this share of the scene depth (at keyframe_depth_quantile)
  /// from every key-frame. 0.08: a point's depth comes from one stereo pair until a second
  /// key-frame sees it, and driving towards it turns that depth error into pixels (a side point
  /// at 8 m, 1.5 m on: 2-3 px, outside the inlier radius); on the street clip (lock step, over
  /// five inlier radii) 0.12 gave 1.026 m mean ATE, 0.10 0.993, 0.08 0.945, 0.07 0.931 with 18 %
  /// more key-frames; on five synth-rig walks 0.08 was better on four (docs/results.md).
  double keyframe_distance_ratio = 0.08;
  /// The quantile of the tracked points' depths that sets the key-frame distance: the near
  /// structure, which leaves the view first (far points would space key-frames too widely).
  double keyframe_depth_quantile = 0.5;
  double keyframe_angle_deg = 12.0;
  double keyframe_track_ratio = 0.5;  //!< fewer tracked points than this x max_tracks: key-frame
  int keyframe_min_frames = 5;  //!< ... but not sooner than this after the last (sparse scenes)
  /// While the camera turns faster than this, a key-frame for distance or angle waits (the
  /// frame is blurred along the turn: corners sit at the ends of their streaks, which would
  /// bias the new points and the key-frame's observations); one for tracks thinning out
  /// (keyframe_track_ratio) does not [deg/s].
  double keyframe_max_turn_deg_s = 60.0;
  /// Motion blur: a frame turning faster than keyframe_max_turn_deg_s sees its points with
  /// 1 + this x the excess rate [deg/s] pixels of error, in its pose (against the gyro's
  /// rotation) and, for a key-frame, in bundle adjustment. The error is a bias along the turn,
  /// not noise, so it is weighted down hard.
  double blur_sigma_px_per_deg_s = 0.5;
  int min_initial_points = 30;  //!< a map needs this many stereo points to start
  int stage2_radius_px = 8;
  int stage2_max_attempts = 200;
  int relocalise_radius_px = 24;
  int relocalise_max_points = 120;
  int relocalise_candidates = 3;    //!< key-frames (by thumbnail) tried per lost frame
  int relocalise_max_hamming = 64;  //!< descriptor distance of a match (of 256 bits)
  float relocalise_ratio = 0.85f;   //!< best / second-best distance must be below
  int relocalise_min_inliers = 25;  //!< an appearance relocalisation needs this many
  /// Lost this many frames in a row without relocalising: start a new map segment at the
  /// predicted pose (0: never).
  int new_segment_after_lost = 5;
  /// While lost, the pose is carried on by the motion model for this many frames, then held.
  int lost_extrapolate_frames = 5;
  float max_patch_cost = 14.0f;  //!< zero-mean SAD per pixel accepted by the patch search
  /// A map point looked for (tracked in stage 1 or searched in stage 2) this many times and
  /// found in fewer than cull_found_ratio of them is dropped (moving objects, repeated texture,
  /// bad matches); the next key-frame's message tells the mapper.
  std::uint32_t cull_after_visible = 20;
  double cull_found_ratio = 0.25;
  double depth_sigma_px = 0.5;  //!< disparity noise for a new point's depth uncertainty
  /// How far the gyro's rotation since the last frame may be trusted (1 sigma) [deg] over
  /// gyro_sigma_interval_s: the pose keeps the predicted rotation within about this (0: the gyro
  /// only seeds the search). Over a longer interval (frames dropped, a slower camera) the sigma
  /// grows in proportion, as a residual bias turns the integrated rotation
  /// (gyro_prior_sigma_deg): a fixed per-frame sigma lets a tracker that skips frames follow the
  /// gyro's residual bias instead of the map.
  /// 0.04: the gyro's own rotation over 50 ms of a still rig is that noisy (EuRoC V1_01's
  /// ADIS16448: median 0.013 deg, 90th percentile 0.063 deg from its raw samples, more through a
  /// BNO055 at 100 Hz that misses samples), while vision alone holds a still camera's frame-to-
  /// frame rotation within 0.001 deg; 0.01 made the pose follow that noise (docs/results.md, HIL).
  double gyro_rotation_sigma_deg = 0.04;
  double gyro_sigma_interval_s = 0.05;
  /// With the accelerometer's specific force in the prior (RotationPrior::accel_valid), the
  /// camera centre is predicted through the head's accelerations, with gravity learnt from the
  /// tracked poses (GravityEstimate: averaged, and gated once enough are in).
  bool accel_prediction = true;
  GravityParams gravity;
  /// A distorted rig's right image is rectified only where the stereo search reads it (the
  /// same bytes there; false: all of it every frame, as a reference).
  bool right_on_demand = true;
  DetectorParams detector{.bucket_px = 32};
  KltParams klt;
  StereoMatchParams stereo;
  PoseParams pose;
};

/// One map point (world frame = the first frame's rectified left camera).
struct MapPoint {
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  std::uint32_t generation = 0;    //!< +1 each time the id is reused
  std::int32_t segment = 0;        //!< the map segment that made it
  float sigma_m = 0.0f;            //!< position uncertainty (1 sigma, mostly along the ray)
  std::uint16_t observations = 0;  //!< key-frames that saw it
  bool alive = false;
  std::int32_t keyframe = -1;            //!< the key-frame that made it
  std::int32_t tracked_frame = -1;       //!< last frame it was tracked in
  std::uint32_t visible = 0, found = 0;  //!< frames it was looked for / found
  Patch8 patch;                          //!< its look when made (rectified left image)
  Descriptor256 descriptor;              //!< its appearance when made (for relocalisation)
  bool has_descriptor = false;
  /// Made beyond max_depth_m: its disparity is too small to trust, so it is used for its
  /// bearing only (no stereo residual in the pose or in bundle adjustment).
  bool far = false;
};

/// A map point as the tracker and the mapper name it to each other.
struct PointRef {
  std::int32_t id = -1;
  std::uint32_t generation = 0;
  friend bool operator==(const PointRef&, const PointRef&) = default;
};

/// A map point seen in the last frame, as the tracker measured it there (for embedders that show
/// what is tracked, e.g. the VIT interface's pose features).
struct FrameFeature {
  PointRef point;                  //!< the map point (an id names one point per generation)
  float u_px = 0.0f, v_px = 0.0f;  //!< rectified left image
  float u_right_px = NAN;          //!< rectified right image, same row; NaN: not matched
  float depth_m = 0.0f;            //!< the point's depth in the rectified left camera
};

/// A map point seen in a key-frame.
struct KeyframeObservation {
  std::int32_t point = -1;
  std::uint32_t generation = 0;
  float u_px = 0.0f, v_px = 0.0f;
  float u_right_px = NAN;
};
struct NewMapPoint {
  std::int32_t point = -1;
  std::uint32_t generation = 0;
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  float sigma_m = 0.0f;
};

/// What the tracker hands the mapper for each new key-frame (fixed capacity).
struct KeyframeMessage {
  std::int32_t id = -1;
  TimeNs t_ns = 0;
  SE3d T_world_cam = SE3d::Identity();
  std::int32_t segment = 0;    //!< map segment (a new one starts after a lasting loss)
  bool segment_start = false;  //!< the first key-frame of its segment (holds its gauge)
  /// Its observations' noise [px]: 1, more when the camera was turning (motion blur).
  float observation_sigma_px = 1.0f;
  /// Its rotation was tracked with the gyro's (a bias-corrected rate held the pose): the
  /// mapper then trusts it more than a vision-only one (MapperConfig::keyframe_prior_deg_gyro).
  bool gyro_aided = false;
  FixedVector<KeyframeObservation> observations;
  FixedVector<NewMapPoint> new_points;
  /// Map points the tracker gave up on since the last key-frame (rarely found where predicted).
  FixedVector<PointRef> culled;

  KeyframeMessage() = default;
  KeyframeMessage(std::size_t capacity, std::size_t max_culled)
      : observations(capacity), new_points(capacity), culled(max_culled) {}
  void copy_from(const KeyframeMessage& other);  //!< no allocation: capacities must suffice
};

/// What the mapper hands back after bundle adjustment (fixed capacity).
struct MapCorrection {
  struct Point {
    std::int32_t point = -1;
    std::uint32_t generation = 0;
    Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
    float sigma_m = 0.0f;
  };
  struct Keyframe {
    std::int32_t id = -1;
    SE3d T_world_cam = SE3d::Identity();
  };
  FixedVector<Point> points;
  FixedVector<PointRef> culled;
  FixedVector<Keyframe> keyframes;
  /// Key-frames the mapper dropped as redundant (their points are seen by others).
  FixedVector<std::int32_t> culled_keyframes;

  MapCorrection() = default;
  MapCorrection(std::size_t max_points, std::size_t max_keyframes)
      : points(max_points),
        culled(max_points),
        keyframes(max_keyframes),
        culled_keyframes(max_keyframes) {}
  void clear() {
    points.clear();
    culled.clear();
    keyframes.clear();
    culled_keyframes.clear();
  }
};

/// Per-stage times of one frame, when the caller gives a clock (dsp reads no clock itself).
struct TrackerTimes {
  std::int64_t rectify_ns = 0, pyramid_ns = 0, stage1_ns = 0, stage2_ns = 0, keyframe_ns = 0;
  std::int64_t total_ns = 0;
};

struct TrackResult {
  TimeNs t_ns = 0;
  std::int64_t frame = 0;
  TrackingState state = TrackingState::kInitialising;
  SE3d T_world_cam = SE3d::Identity();  //!< rectified left camera in the world
  int tracked = 0;                      //!< stage-1 tracks that survived
  int found = 0;                        //!< stage-2 re-found points
  int inliers = 0;
  double rms_px = 0.0;
  int new_points = 0;
  bool keyframe = false;
  bool relocalised = false;
  std::int32_t segment = 0;        //!< the map segment the pose belongs to
  bool new_segment = false;        //!< this frame started a new segment (after a lasting loss)
  bool map_full = false;           //!< a key-frame could not add every point: the map is full
  bool keyframe_deferred = false;  //!< a key-frame was due but not allowed (mapper behind)
  /// Corrections or culls ignored since the last frame because they named an older generation.
  int stale_updates = 0;
  /// The frame was not used: not 8-bit gray, or not the calibration's size. The state and the
  /// pose are the last frame's.
  const char* rejected = nullptr;
  TrackerTimes times;
};

/// An optional rotation prior: the rectified left camera's rotation from the last frame to this
/// one (R_prev_cur), e.g. integrated from the gyro.
struct RotationPrior {
  bool valid = false;
  Eigen::Quaterniond q_prev_cur = Eigen::Quaterniond::Identity();
  /// The rates were corrected by a known gyro bias: the rotation may hold the pose
  /// (TrackerConfig::gyro_rotation_sigma_deg). Otherwise it only seeds the search (a bias of
  /// a few deg/s would turn a still camera).
  bool bias_corrected = false;
  /// The accelerometer's specific force integrated once and twice over the same interval, in
  /// the IMU frame at the last frame (GyroDelta::dv_m_s, dp_m). With them and the gravity the
  /// tracker learns from its own poses, the camera centre is predicted through the head's
  /// accelerations (a quick turn swings the camera about the neck) instead of at constant
  /// velocity.
  bool accel_valid = false;
  Eigen::Vector3d dv_imu_m_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d dp_imu_m = Eigen::Vector3d::Zero();
};

/// The 1-sigma trust [deg] of the gyro's rotation over `dt_s` since the last tracked frame:
/// config.gyro_rotation_sigma_deg up to config.gyro_sigma_interval_s, growing in proportion
/// beyond it (0 when the gyro only seeds the search).
double gyro_prior_sigma_deg(const TrackerConfig& config, double dt_s);

/// The predicted pose (T_cam_world) of the next frame from the last one, `T_cw_last`, and the
/// last frame-to-frame motion `velocity` (T_cam(last)_cam(before)): the camera centre moves on
/// by its last displacement in the world (constant velocity); the rotation is the gyro's when
/// given, else the last frame-to-frame rotation again. Composing the relative motion keeps the
/// centre where the motion puts it, wherever the camera is (replacing the rotation of a
/// world-to-camera transform and keeping its translation would swing the centre about the
/// world origin by the turn's angle).
SE3d predict_camera_pose(const SE3d& T_cw_last, const SE3d& velocity, const RotationPrior& gyro);

class Tracker {
 public:
  using Clock = std::int64_t (*)();
  /// Throws std::invalid_argument for a rig the rectifier cannot use or bad capacities.
  Tracker(const RigCalibration& rig, const TrackerConfig& config, Clock clock = nullptr);
  ~Tracker();
  Tracker(const Tracker&) = delete;
  Tracker& operator=(const Tracker&) = delete;

  /// Tracks one stereo pair. A pair that is not 8-bit gray of the calibration's size is not
  /// used: the result says why (`rejected`) and keeps the last state and pose.
  TrackResult track(TimeNs t_ns, const Image& left, const Image& right,
                    const RotationPrior& gyro = {});

  /// The key-frame made by the last track(), or nullptr.
  [[nodiscard]] const KeyframeMessage* pending_keyframe() const;
  /// Applies the mapper's corrected points and key-frame poses; the current pose moves with its
  /// reference key-frame. Never allocates.
  void apply(const MapCorrection& correction);
  /// Forgets the map and starts again with the next frame.
  void reset();
  /// Whether track() may make key-frames (false while the mapper is behind: the tracker keeps
  /// tracking on the map it has and says so in TrackResult::keyframe_deferred).
  void set_keyframes_allowed(bool allowed);

  [[nodiscard]] TrackingState state() const;
  [[nodiscard]] const StereoIntrinsics& intrinsics() const;
  /// Rectified left camera -> the rig's body frame (T_body_cam0 * R1^T).
  [[nodiscard]] const SE3d& T_body_rect() const;
  [[nodiscard]] std::span<const MapPoint> map_points() const;
  /// The last frame's tracked points (its pose's inliers, and a key-frame's new points) into
  /// `out`, at most out.size() of them; returns how many. None unless that frame was tracked.
  /// Never allocates.
  std::size_t frame_features(std::span<FrameFeature> out) const;
  [[nodiscard]] const TrackerConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wallar::dsp
