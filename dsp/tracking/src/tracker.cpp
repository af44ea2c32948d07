// SPDX-License-Identifier: Apache-2.0
/// @file tracker.cpp
/// @brief Rectify, predict, track (LK + stereo + RANSAC/Gauss-Newton), re-find by patches,
/// relocalise, and make key-frames with new map points. All storage is sized in the constructor.
#include "wallar/dsp/tracking/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <stdexcept>

#include "wallar/dsp/stereo/rectifier.hpp"
#include "wallar/dsp/tracking/accel_prediction.hpp"

namespace wallar::dsp {

const char* to_string(TrackingState state) {
  switch (state) {
    case TrackingState::kInitialising:
      return "initialising";
    case TrackingState::kTracking:
      return "tracking";
    case TrackingState::kLost:
      return "lost";
  }
  return "?";
}

void KeyframeMessage::copy_from(const KeyframeMessage& other) {
  id = other.id;
  t_ns = other.t_ns;
  T_world_cam = other.T_world_cam;
  observations.clear();
  for (const KeyframeObservation& o : other.observations) observations.push_back(o);
  new_points.clear();
  for (const NewMapPoint& p : other.new_points) new_points.push_back(p);
  segment = other.segment;
  segment_start = other.segment_start;
  observation_sigma_px = other.observation_sigma_px;
  gyro_aided = other.gyro_aided;
  culled.clear();
  for (const PointRef& point : other.culled) culled.push_back(point);
}

double gyro_prior_sigma_deg(const TrackerConfig& config, double dt_s) {
  if (config.gyro_rotation_sigma_deg <= 0.0) return 0.0;
  if (config.gyro_sigma_interval_s <= 0.0 || dt_s <= config.gyro_sigma_interval_s) {
    return config.gyro_rotation_sigma_deg;
  }
  return config.gyro_rotation_sigma_deg * dt_s / config.gyro_sigma_interval_s;
}

SE3d predict_camera_pose(const SE3d& T_cw_last, const SE3d& velocity, const RotationPrior& gyro) {
  const Eigen::Matrix3d& R_last = T_cw_last.linear();
  const Eigen::Vector3d c_last = -R_last.transpose() * T_cw_last.translation();
  const SE3d T_cw_before = velocity.inverse() * T_cw_last;
  const Eigen::Vector3d c_before = -T_cw_before.linear().transpose() * T_cw_before.translation();
  const Eigen::Vector3d c_pred = c_last + (c_last - c_before);
  const Eigen::Matrix3d R_cur_last =
      gyro.valid ? gyro.q_prev_cur.conjugate().toRotationMatrix() : velocity.linear();
  SE3d T = SE3d::Identity();
  T.linear() = R_cur_last * R_last;
  T.translation() = -T.linear() * c_pred;
  return orthonormalised(T);
}

namespace {

constexpr int kThumbBlock = 16;  //!< thumbnails average 16x16 blocks (PTAM's small blurry image)

/// A map point tracked in the current frame.
struct Track {
  std::int32_t point = -1;
  float u_px = 0.0f, v_px = 0.0f;
  float u_right_px = NAN;
};

struct KeyframeRecord {
  std::int32_t id = -1;  //!< -1: a free record
  TimeNs t_ns = 0;
  SE3d T_world_cam = SE3d::Identity();
  std::int32_t segment = 0;
  FixedVector<PointRef> points;  //!< map points it observed
  std::vector<float> thumbnail;  //!< zero-mean block averages, sized once
};

/// A corner of the frame being relocalised, with its descriptor and (lazily) its right match.
struct RelocCorner {
  float u_px = 0.0f, v_px = 0.0f;
  Descriptor256 descriptor;
  bool has_descriptor = false;
  bool right_tried = false;
  float u_right_px = NAN;
};

double rotation_angle_deg(const Eigen::Matrix3d& R) {
  const double c = std::clamp((R.trace() - 1.0) * 0.5, -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

}  // namespace

struct Tracker::Impl {
  TrackerConfig config;
  Clock clock = nullptr;
  int width = 0, height = 0;
  StereoIntrinsics K;
  double far_depth_m = 0.0;  // config.far_depth_m, or the rig's 4 px disparity
  SE3d T_body_rect = SE3d::Identity();
  std::array<RemapTable, 2> remap;
  std::array<GrayImage, 2> rect;  // current rectified left, right
  // A distorted rig's right image is rectified on demand: the source, and per row and block of
  // kRightBlock columns whether it is rectified yet this frame.
  static constexpr int kRightBlock = 8;
  GrayView right_source;
  bool right_lazy = false;  // this frame
  int right_blocks = 0;     // per row
  std::vector<std::uint8_t> right_done;
  std::array<Pyramid, 2> pyramid;  // left pyramids: [cur_pyr] this frame, the other the last
  int cur_pyr = 0;
  CornerDetector detector;
  FixedVector<Corner> corners;
  std::vector<std::uint16_t> occupancy;

  FixedVector<MapPoint> points;
  FixedVector<std::int32_t> free_points;
  FixedVector<Track> tracks, next_tracks;
  FixedVector<PoseObservation> obs;
  FixedVector<std::int32_t> obs_point;
  FixedVector<std::uint8_t> inlier;
  FixedVector<std::int32_t> candidates;
  FixedVector<PointRef> pending_culls;  // culled since the last key-frame's message
  FixedVector<std::int32_t> attempted;  // stage 1's tracks this frame
  FixedVector<RelocCorner> reloc_corners;
  FixedVector<float> brightness_prev, brightness_cur;  // stage 1's exposure samples

  std::vector<KeyframeRecord> keyframes;  // a pool of max_keyframes records (id -1: free)
  std::int32_t next_keyframe = 0;
  std::int32_t reference_keyframe = -1;
  std::vector<float> thumbnail;  // this frame's
  int thumb_w = 0, thumb_h = 0;
  KeyframeMessage message;
  bool message_pending = false;
  bool keyframes_allowed = true;
  int stale_updates = 0;

  TrackingState state = TrackingState::kInitialising;
  SE3d T_cw = SE3d::Identity();       // camera <- world, this frame
  SE3d T_cw_last = SE3d::Identity();  // the last frame's
  SE3d velocity = SE3d::Identity();   // T_cw = velocity * T_cw_last, constant velocity model
  std::int64_t frame = -1;
  std::int64_t last_keyframe_frame = -1;
  std::uint32_t stage2_offset = 0;
  std::int32_t segment = 0;
  bool segment_started = false;       // the current segment has made its first key-frame
  int lost_frames = 0;                // in a row
  bool stage2_ran = false;            // this frame
  bool gyro_prior_valid = false;      // this frame: the gyro's rotation, gyro_R_cw, holds the pose
  double observation_sigma_px = 1.0;  // this frame's (motion blur)
  double turn_rate_deg_s = 0.0;       // this frame's
  TimeNs last_t_ns = 0;               // the last frame's time
  Eigen::Matrix3d gyro_R_cw = Eigen::Matrix3d::Identity();
  double gyro_sigma_deg = 0.0;   // this frame's trust in gyro_R_cw (gyro_prior_sigma_deg)
  bool pose_gyro_aided = false;  // this frame's pose was solved with the gyro's rotation prior

  // The accelerometer-aided prediction of the camera centre (predict_centre).
  SE3d T_rect_imu = SE3d::Identity();
  SE3d T_cw_before = SE3d::Identity();  // the frame before the last one's
  bool accel_last = false;  // the last interval was tracked at both ends, with its specific force
  SpecificForceInterval last_force;
  GravityEstimate gravity;  // in the map's world

  std::int64_t now() const { return clock != nullptr ? clock() : 0; }
  /// solve() holds the rotation near the gyro's this frame.
  bool gyro_prior_active() const { return gyro_prior_valid && gyro_sigma_deg > 0.0; }
  KeyframeRecord* keyframe_by_id(std::int32_t id) {
    if (id < 0) return nullptr;
    for (KeyframeRecord& k : keyframes) {
      if (k.id == id) return &k;
    }
    return nullptr;
  }
  /// A free record, else the oldest one (the mapper keeps every key-frame; the tracker's records
  /// are for relocalisation and key-frame spacing).
  KeyframeRecord& record_for_new_keyframe() {
    KeyframeRecord* oldest = &keyframes.front();
    for (KeyframeRecord& k : keyframes) {
      if (k.id < 0) return k;
      if (k.id < oldest->id) oldest = &k;
    }
    return *oldest;
  }
  bool alive(const PointRef& ref) const {
    if (ref.id < 0 || static_cast<std::size_t>(ref.id) >= points.size()) return false;
    const MapPoint& p = points[static_cast<std::size_t>(ref.id)];
    return p.alive && p.generation == ref.generation;
  }
  PointRef ref_of(std::int32_t id) const {
    return PointRef{id, points[static_cast<std::size_t>(id)].generation};
  }

  /// A far point's bearing counts less the farther it is (its depth came from a disparity of a
  /// few pixels and would steer the translation); near points count fully.
  float observation_weight(const MapPoint& p, double depth) const {
    if (!p.far || !(depth > config.max_depth_m)) return 1.0f;
    const double r = config.max_depth_m / depth;
    return static_cast<float>(r * r);
  }
  /// What the pose sees of map point `p` at (u, v) in the left image (u_right: NaN when the
  /// right image did not see it; a far point is used for its bearing only).
  static PoseObservation observation_of(const MapPoint& p, float u, float v, float u_right,
                                        float weight) {
    PoseObservation o;
    o.p_world = p.p_world;
    o.sigma_m = p.sigma_m;
    o.weight = weight;
    o.u_px = u;
    o.v_px = v;
    o.u_right_px = p.far ? NAN : u_right;
    return o;
  }
  void make_thumbnail(const GrayView& img, std::vector<float>& out) const;
  const char* check(const Image& left, const Image& right) const;
  void rectify(const Image& left, const Image& right);
  bool project(const SE3d& T, const Eigen::Vector3d& p_world, double margin, Eigen::Vector3d& uvr,
               double& depth) const;
  std::optional<float> right_u(float u, float v, double depth_hint);
  void right_ready(const PixelRect& r);
  std::int32_t new_point(const Eigen::Vector3d& p_world, float sigma, float u, float v);
  void free_point(std::int32_t id);
  int add_stereo_points(bool& map_full);
  void stage1(const SE3d& prior, TrackResult& result);
  void stage2(int radius, TrackResult& result, const KeyframeRecord* only);
  PoseResult solve(const SE3d& prior, bool ransac);
  void keep_inlier_tracks();
  void rank_keyframes(std::array<const KeyframeRecord*, 8>& best, int& n);
  bool relocalise_by_appearance(const KeyframeRecord& k, TrackResult& result);
  bool relocalise_by_patches(const KeyframeRecord& k, TrackResult& result);
  bool relocalise(TrackResult& result);
  bool need_keyframe() const;
  void make_keyframe(TimeNs t_ns, TrackResult& result);
  void cull_points();
  void initialise(TimeNs t_ns, TrackResult& result);
  void clear_map();
  /// The IMU's pose (world <- IMU) at camera pose T_cam_world.
  SE3d T_world_imu(const SE3d& T_cam_world) const { return T_cam_world.inverse() * T_rect_imu; }
  void predict_centre(const RotationPrior& imu, double dt_s, SE3d& prior) const;
  void learn_gravity(const RotationPrior& imu, double dt_s);
};

/// The camera centre moved through the head's accelerations (accel_prediction.hpp): the IMU
/// goes on at its last velocity, plus gravity and its specific force over the interval, and the
/// camera sits where the gyro's rotation puts it about the IMU. `prior` keeps its rotation.
void Tracker::Impl::predict_centre(const RotationPrior& imu, double dt_s, SE3d& prior) const {
  if (!imu.accel_valid || !accel_last || gravity.samples() == 0 || !(dt_s > 0.0)) return;
  const SpecificForceInterval next{imu.dv_imu_m_s, imu.dp_imu_m, dt_s};
  const Eigen::Vector3d p_imu = predict_imu_position(
      T_world_imu(T_cw_before), T_world_imu(T_cw_last), last_force, next, gravity.value());
  // T_world_cam = T_world_imu T_imu_rect: the camera's centre from the IMU's.
  const Eigen::Vector3d c = p_imu - prior.linear().transpose() * T_rect_imu.translation();
  prior.translation() = -prior.linear() * c;
}

/// Gravity in the map's world (GravityEstimate): the first estimate from the specific force
/// alone (at rest at the start it is minus gravity), then the estimates from the poses
/// (gravity_from_poses).
void Tracker::Impl::learn_gravity(const RotationPrior& imu, double dt_s) {
  if (!imu.accel_valid || !(dt_s > 0.0)) return;
  if (gravity.samples() == 0) {
    gravity.add(-T_world_imu(T_cw_last).linear() * imu.dv_imu_m_s / dt_s);
    return;
  }
  if (!accel_last) return;
  gravity.add(gravity_from_poses(T_world_imu(T_cw_before), T_world_imu(T_cw_last),
                                 T_world_imu(T_cw), last_force,
                                 SpecificForceInterval{imu.dv_imu_m_s, imu.dp_imu_m, dt_s}));
}

Tracker::Tracker(const RigCalibration& rig, const TrackerConfig& config, Clock clock)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.config = config;
  m.clock = clock;
  if (config.max_tracks < 8 || config.max_map_points < config.max_tracks ||
      config.max_keyframes < 2 || config.pyramid_levels < 2) {
    throw std::invalid_argument(
        "tracker: capacities too small (max_tracks >= 8, max_map_points >= max_tracks, "
        "max_keyframes >= 2, pyramid_levels >= 2)");
  }
  const Rectifier rectifier(rig);
  m.width = rectifier.size().width;
  m.height = rectifier.size().height;
  m.K = StereoIntrinsics{rectifier.f_px(), rectifier.cx(), rectifier.cy(), rectifier.baseline_m()};
  m.far_depth_m =
      std::max(config.max_depth_m,
               config.far_depth_m > 0.0 ? config.far_depth_m : m.K.f_px * m.K.baseline_m / 4.0);
  SE3d T_cam0_rect = SE3d::Identity();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) T_cam0_rect.linear()(i, j) = rectifier.R(0)(j, i);
  }
  m.T_body_rect = rig.cams[0].T_body_cam * T_cam0_rect;
  m.T_rect_imu = m.T_body_rect.inverse() * rig.imu.T_body_imu;
  m.gravity = GravityEstimate(config.gravity);
  for (int cam = 0; cam < 2; ++cam) {
    cv::Mat map_x, map_y;
    cv::initUndistortRectifyMap(rectifier.K(cam), rectifier.dist(cam), rectifier.R(cam),
                                rectifier.P(cam), rectifier.size(), CV_32FC1, map_x, map_y);
    const std::size_t n = static_cast<std::size_t>(m.width) * static_cast<std::size_t>(m.height);
    m.remap[static_cast<std::size_t>(cam)] =
        RemapTable(m.width, m.height, std::span<const float>(map_x.ptr<float>(), n),
                   std::span<const float>(map_y.ptr<float>(), n), m.width, m.height);
    m.rect[static_cast<std::size_t>(cam)].allocate(m.width, m.height);
  }
  m.right_blocks = (m.width + Impl::kRightBlock - 1) / Impl::kRightBlock;
  m.right_done.assign(static_cast<std::size_t>(m.height * m.right_blocks), 0);
  for (Pyramid& p : m.pyramid) p = Pyramid(m.width, m.height, config.pyramid_levels);
  m.detector = CornerDetector(m.width, m.height, config.detector);
  const auto max_tracks = static_cast<std::size_t>(config.max_tracks);
  const auto max_points = static_cast<std::size_t>(config.max_map_points);
  const auto keyframe_points = static_cast<std::size_t>(config.keyframe_points);
  m.corners = FixedVector<Corner>(keyframe_points);
  m.reloc_corners = FixedVector<RelocCorner>(keyframe_points);
  m.occupancy.assign(static_cast<std::size_t>(m.detector.bucket_count()), 0);
  m.points = FixedVector<MapPoint>(max_points);
  m.free_points = FixedVector<std::int32_t>(max_points);
  m.tracks = FixedVector<Track>(max_tracks);
  m.next_tracks = FixedVector<Track>(max_tracks);
  // Relocalisation and stage 2 may gather more observations than tracks.
  const std::size_t max_obs =
      max_tracks + keyframe_points +
      static_cast<std::size_t>(std::max(config.stage2_max_attempts, config.relocalise_max_points));
  m.obs = FixedVector<PoseObservation>(max_obs);
  m.obs_point = FixedVector<std::int32_t>(max_obs);
  m.inlier = FixedVector<std::uint8_t>(max_obs);
  m.candidates = FixedVector<std::int32_t>(max_points);
  m.pending_culls = FixedVector<PointRef>(max_points);
  m.attempted = FixedVector<std::int32_t>(max_tracks);
  m.brightness_prev = FixedVector<float>(max_tracks);
  m.brightness_cur = FixedVector<float>(max_tracks);
  m.thumb_w = m.width / kThumbBlock;
  m.thumb_h = m.height / kThumbBlock;
  m.thumbnail.resize(static_cast<std::size_t>(m.thumb_w * m.thumb_h));
  m.keyframes.resize(static_cast<std::size_t>(config.max_keyframes));
  for (KeyframeRecord& k : m.keyframes) {
    k.points = FixedVector<PointRef>(max_tracks + keyframe_points);
    k.thumbnail.resize(m.thumbnail.size());
  }
  m.message = KeyframeMessage(max_tracks + keyframe_points, max_points);
}

Tracker::~Tracker() = default;

TrackingState Tracker::state() const { return impl_->state; }
const StereoIntrinsics& Tracker::intrinsics() const { return impl_->K; }
const SE3d& Tracker::T_body_rect() const { return impl_->T_body_rect; }
std::span<const MapPoint> Tracker::map_points() const { return impl_->points.span(); }
const TrackerConfig& Tracker::config() const { return impl_->config; }
std::size_t Tracker::frame_features(std::span<FrameFeature> out) const {
  const Impl& m = *impl_;
  if (m.state != TrackingState::kTracking) return 0;
  std::size_t n = 0;
  for (const Track& t : m.tracks.span()) {
    if (n == out.size()) break;
    const MapPoint& p = m.points[static_cast<std::size_t>(t.point)];
    const double depth_m = (m.T_cw * p.p_world).z();
    if (!p.alive || !(depth_m > 0.0)) continue;
    out[n++] = {PointRef{t.point, p.generation}, t.u_px, t.v_px, t.u_right_px,
                static_cast<float>(depth_m)};
  }
  return n;
}
const KeyframeMessage* Tracker::pending_keyframe() const {
  return impl_->message_pending ? &impl_->message : nullptr;
}
void Tracker::set_keyframes_allowed(bool allowed) { impl_->keyframes_allowed = allowed; }

void Tracker::Impl::clear_map() {
  // Generations survive a reset, so a message about an old point can never match a new one.
  for (MapPoint& p : points) {
    p.alive = false;
    ++p.generation;
  }
  free_points.clear();
  for (std::size_t i = points.size(); i-- > 0;) free_points.push_back(static_cast<std::int32_t>(i));
  pending_culls.clear();
  tracks.clear();
  for (KeyframeRecord& k : keyframes) k.id = -1;
  reference_keyframe = -1;
}

void Tracker::reset() {
  Impl& m = *impl_;
  m.clear_map();
  m.next_keyframe = 0;
  m.segment = 0;
  m.segment_started = false;
  m.lost_frames = 0;
  m.state = TrackingState::kInitialising;
  m.T_cw = m.T_cw_last = m.velocity = m.T_cw_before = SE3d::Identity();
  m.accel_last = false;
  m.gravity.reset();
  m.message_pending = false;
}

void Tracker::Impl::make_thumbnail(const GrayView& img, std::vector<float>& out) const {
  double mean = 0.0;
  for (int ty = 0; ty < thumb_h; ++ty) {
    for (int tx = 0; tx < thumb_w; ++tx) {
      int sum = 0;
      for (int y = 0; y < kThumbBlock; ++y) {
        const std::uint8_t* r = img.row(ty * kThumbBlock + y) + tx * kThumbBlock;
        for (int x = 0; x < kThumbBlock; ++x) sum += r[x];
      }
      const float v = static_cast<float>(sum) / (kThumbBlock * kThumbBlock);
      out[static_cast<std::size_t>(ty * thumb_w + tx)] = v;
      mean += v;
    }
  }
  mean /= static_cast<double>(out.size());
  // Zero mean and unit spread: an exposure change does not make a place look different.
  double var = 0.0;
  for (float& v : out) {
    v -= static_cast<float>(mean);
    var += static_cast<double>(v) * v;
  }
  const double sd = std::sqrt(var / static_cast<double>(out.size()));
  if (sd > 1e-3) {
    for (float& v : out) v = static_cast<float>(v / sd);
  }
}

const char* Tracker::Impl::check(const Image& left, const Image& right) const {
  for (const Image* im : {&left, &right}) {
    if (im->empty() || im->format() != PixelFormat::kGray8) return "not an 8-bit gray image";
    if (im->width() != width || im->height() != height) {
      return "the image size differs from the calibration's";
    }
  }
  return nullptr;
}

void Tracker::Impl::rectify(const Image& left, const Image& right) {
  remap[0].apply(GrayView{left.data(), left.width(), left.height(), left.stride_bytes()},
                 rect[0].data());
  right_source = GrayView{right.data(), right.width(), right.height(), right.stride_bytes()};
  // An identity table copies rows (cheap); a distorted rig's right image is only read along the
  // rows the stereo search visits, so it is rectified there, on demand (right_ready).
  right_lazy = config.right_on_demand && !remap[1].identity();
  if (right_lazy) {
    std::fill(right_done.begin(), right_done.end(), std::uint8_t{0});
  } else {
    remap[1].apply(right_source, rect[1].data());
  }
}

/// Rectifies what `r` covers of the right image that is not yet this frame, in whole blocks of
/// kRightBlock columns (runs of them at a time).
void Tracker::Impl::right_ready(const PixelRect& r) {
  if (!right_lazy || r.empty()) return;
  const auto w = static_cast<std::size_t>(width);
  const int b0 = r.x0 / kRightBlock, b1 = (r.x1 - 1) / kRightBlock + 1;
  for (int y = r.y0; y < r.y1; ++y) {
    std::uint8_t* done = right_done.data() + static_cast<std::ptrdiff_t>(y) * right_blocks;
    const std::size_t row = static_cast<std::size_t>(y) * w;
    for (int b = b0; b < b1;) {
      if (done[b] != 0) {
        ++b;
        continue;
      }
      int e = b;
      while (e < b1 && done[e] == 0) done[e++] = 1;
      const std::size_t x0 = static_cast<std::size_t>(b * kRightBlock);
      const std::size_t x1 = std::min(w, static_cast<std::size_t>(e * kRightBlock));
      remap[1].apply_span(right_source, rect[1].data(), row + x0, x1 - x0);
      b = e;
    }
  }
}

bool Tracker::Impl::project(const SE3d& T, const Eigen::Vector3d& p_world, double margin,
                            Eigen::Vector3d& uvr, double& depth) const {
  const Eigen::Vector3d p = T * p_world;
  depth = p.z();
  if (!(depth > config.min_depth_m * 0.5) || depth > far_depth_m * 1.5) return false;
  uvr = K.project(p);
  return uvr.x() >= margin && uvr.y() >= margin && uvr.x() < width - 1 - margin &&
         uvr.y() < height - 1 - margin;
}

std::optional<float> Tracker::Impl::right_u(float u, float v, double depth_hint) {
  int d_min = 0, d_max = 0;
  if (depth_hint > 0.0) {
    const double d = K.f_px * K.baseline_m / depth_hint;
    d_min = static_cast<int>(std::floor(d * 0.8)) - 3;
    d_max = static_cast<int>(std::ceil(d * 1.25)) + 3;
  } else {
    // The whole row from (almost) infinity: a search window that stopped at the far depth limit
    // would hand a point beyond it the best wrong match inside (repeated facades, fences). The
    // depth limits are applied to the match found.
    d_min = 0;
    d_max = static_cast<int>(std::ceil(K.f_px * K.baseline_m / config.min_depth_m));
  }
  right_ready(match_along_row_reads(width, height, u, v, d_min, d_max, config.stereo));
  const std::optional<float> d =
      match_along_row(rect[0].view(), rect[1].view(), u, v, d_min, d_max, config.stereo);
  if (!d) return std::nullopt;
  return u - *d;
}

std::int32_t Tracker::Impl::new_point(const Eigen::Vector3d& p_world, float sigma, float u,
                                      float v) {
  std::int32_t id = -1;
  if (!free_points.empty()) {
    id = free_points.back();
    free_points.pop_back();
  } else if (points.push_back(MapPoint{})) {
    id = static_cast<std::int32_t>(points.size() - 1);
  } else {
    return -1;  // the map is full
  }
  MapPoint& p = points[static_cast<std::size_t>(id)];
  const std::uint32_t generation = p.generation + 1;  // a reused id names a new point
  p = MapPoint{};
  p.generation = generation;
  p.p_world = p_world;
  p.sigma_m = sigma;
  p.alive = true;
  p.segment = segment;
  p.keyframe = next_keyframe;
  p.tracked_frame = static_cast<std::int32_t>(frame);
  extract_patch(rect[0].view(), u, v, p.patch);
  p.has_descriptor =
      compute_descriptor(pyramid[static_cast<std::size_t>(cur_pyr)].level(1), u, v, p.descriptor);
  return id;
}

void Tracker::Impl::free_point(std::int32_t id) {
  MapPoint& p = points[static_cast<std::size_t>(id)];
  p.alive = false;
  free_points.push_back(id);  // capacity = max points: never full while a point is alive
}

/// New map points from corners in buckets that hold fewer than per_bucket tracks, matched along
/// the rows and triangulated. Each is observed by the key-frame being made (message) and tracked
/// from now on while there is room for tracks; the others wait in the map for stage 2.
int Tracker::Impl::add_stereo_points(bool& map_full) {
  std::fill(occupancy.begin(), occupancy.end(), std::uint16_t{0});
  for (const Track& t : tracks) {
    ++occupancy[static_cast<std::size_t>(detector.bucket_of(t.u_px, t.v_px))];
  }
  detector.detect(rect[0].view(), occupancy, corners);
  const SE3d T_wc = T_cw.inverse();
  int added = 0;
  const auto add = [&](const Corner& c, float ur, const Eigen::Vector3d& p_cam, bool is_far) {
    const float sigma =
        static_cast<float>(p_cam.z() * p_cam.z() / (K.f_px * K.baseline_m) * config.depth_sigma_px);
    if (message.observations.full()) return false;
    const std::int32_t id = new_point(T_wc * p_cam, sigma, c.u_px, c.v_px);
    if (id < 0) {
      map_full = true;  // counted: the key-frame adds fewer points than it could
      return false;
    }
    MapPoint& p = points[static_cast<std::size_t>(id)];
    p.far = is_far;
    if (is_far) ur = NAN;                             // its bearing only
    tracks.push_back(Track{id, c.u_px, c.v_px, ur});  // false when the tracks are full
    message.observations.push_back(KeyframeObservation{id, p.generation, c.u_px, c.v_px, ur});
    message.new_points.push_back(NewMapPoint{id, p.generation, p.p_world, sigma});
    ++added;
    return true;
  };
  // Near points first; the corners matched beyond max_depth_m are kept aside (their disparity
  // in u_px's place) in case too few near ones are found.
  std::size_t far = 0;
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const Corner& c = corners[i];
    const std::optional<float> ur = right_u(c.u_px, c.v_px, -1.0);
    if (!ur) continue;
    const Eigen::Vector3d p_cam = K.triangulate(c.u_px, c.v_px, c.u_px - *ur);
    if (p_cam.z() < config.min_depth_m || p_cam.z() > far_depth_m) continue;
    if (p_cam.z() > config.max_depth_m) {
      corners[far++] = Corner{c.u_px, c.v_px, *ur};  // shi_tomasi holds u_right here
      continue;
    }
    if (!add(c, *ur, p_cam, false)) return added;
  }
  if (static_cast<double>(tracks.size()) >= config.min_near_share * config.max_tracks) {
    return added;
  }
  for (std::size_t i = 0; i < far; ++i) {
    const Corner& c = corners[i];
    const float ur = c.shi_tomasi;
    if (!add(c, ur, K.triangulate(c.u_px, c.v_px, c.u_px - ur), true)) break;
  }
  return added;
}

PoseResult Tracker::Impl::solve(const SE3d& prior, bool ransac) {
  PoseParams params = config.pose;
  if (!ransac) params.ransac_iterations = 0;
  if (gyro_prior_active()) {
    // Against observations of observation_sigma_px noise (the pixel terms count 1/sigma^2).
    const double sigma_rad = gyro_sigma_deg * M_PI / 180.0;
    params.rotation_prior_weight =
        observation_sigma_px * observation_sigma_px / (sigma_rad * sigma_rad);
    params.R_prior_cw = gyro_R_cw;
  }
  inlier.resize(obs.size());
  return estimate_pose(K, obs.span(), prior, inlier.span(),
                       static_cast<std::uint64_t>(frame) * 7919u + 17u, params);
}

/// Keeps the tracks whose observation was an inlier (obs and tracks are index-aligned).
void Tracker::Impl::keep_inlier_tracks() {
  next_tracks.clear();
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (inlier[i] == 0) continue;
    const PoseObservation& o = obs[i];
    if (!next_tracks.push_back(Track{obs_point[i], o.u_px, o.v_px, o.u_right_px})) break;
    MapPoint& p = points[static_cast<std::size_t>(obs_point[i])];
    p.tracked_frame = static_cast<std::int32_t>(frame);
  }
  std::swap(tracks, next_tracks);
}

void Tracker::Impl::stage1(const SE3d& prior, TrackResult& result) {
  const Pyramid& prev = pyramid[static_cast<std::size_t>(1 - cur_pyr)];
  const Pyramid& cur = pyramid[static_cast<std::size_t>(cur_pyr)];
  // The frames' brightness relation (an exposure step) from the tracks' neighbourhoods at the
  // predicted places, on level 2 (the means of 4x4 blocks: little depends on the prediction's
  // pixel error there).
  Brightness brightness;
  {
    const int level = std::min(2, prev.levels() - 1);
    const GrayView P = prev.level(level), C = cur.level(level);
    const float scale = 1.0f / static_cast<float>(1 << level);
    brightness_prev.clear();
    brightness_cur.clear();
    for (const Track& t : tracks) {
      MapPoint& p = points[static_cast<std::size_t>(t.point)];
      Eigen::Vector3d uvr;
      double depth = 0.0;
      if (!p.alive || !project(prior, p.p_world, 0.0, uvr, depth)) continue;
      const float px = (t.u_px + 0.5f) * scale - 0.5f, py = (t.v_px + 0.5f) * scale - 0.5f;
      const float cx = (static_cast<float>(uvr.x()) + 0.5f) * scale - 0.5f;
      const float cy = (static_cast<float>(uvr.y()) + 0.5f) * scale - 0.5f;
      if (!P.inside(px, py, 1.0f) || !C.inside(cx, cy, 1.0f)) continue;
      brightness_prev.push_back(P.sample(px, py));
      brightness_cur.push_back(C.sample(cx, cy));
    }
    brightness = estimate_brightness(brightness_prev.span(), brightness_cur.span());
  }
  obs.clear();
  obs_point.clear();
  attempted.clear();
  candidates.clear();
  for (const Track& t : tracks) {
    MapPoint& p = points[static_cast<std::size_t>(t.point)];
    if (!p.alive) continue;
    attempted.push_back(t.point);
    Eigen::Vector3d uvr;
    double depth = 0.0;
    float u = t.u_px, v = t.v_px;
    if (project(prior, p.p_world, 0.0, uvr, depth)) {
      u = static_cast<float>(uvr.x());
      v = static_cast<float>(uvr.y());
    }
    if (!klt_track(prev, cur, t.u_px, t.v_px, u, v, config.klt, brightness)) continue;
    const std::optional<float> ur = p.far ? std::nullopt : right_u(u, v, depth);
    obs.push_back(observation_of(p, u, v, ur ? *ur : NAN, observation_weight(p, depth)));
    obs_point.push_back(t.point);
    p.tracked_frame = static_cast<std::int32_t>(frame);  // stage 2 leaves it alone
  }
  result.tracked = static_cast<int>(obs.size());
}

/// Searches map points in view that are not tracked this frame by their patches. With `only`,
/// just that key-frame's points (relocalisation). Points of other map segments are not searched
/// (their world drifted from this one's).
void Tracker::Impl::stage2(int radius, TrackResult& result, const KeyframeRecord* only) {
  stage2_ran = true;
  candidates.clear();
  std::fill(occupancy.begin(), occupancy.end(), std::uint16_t{0});
  for (std::size_t i = 0; i < obs.size(); ++i) {
    ++occupancy[static_cast<std::size_t>(detector.bucket_of(obs[i].u_px, obs[i].v_px))];
  }
  const int limit = only != nullptr ? config.relocalise_max_points : config.stage2_max_attempts;
  const auto consider = [&](std::int32_t id) {
    MapPoint& p = points[static_cast<std::size_t>(id)];
    if (!p.alive || p.segment != segment || p.tracked_frame == static_cast<std::int32_t>(frame)) {
      return;
    }
    Eigen::Vector3d uvr;
    double depth = 0.0;
    if (!project(T_cw, p.p_world, 8.0, uvr, depth)) return;
    const int b = detector.bucket_of(static_cast<float>(uvr.x()), static_cast<float>(uvr.y()));
    if (occupancy[static_cast<std::size_t>(b)] >= config.detector.per_bucket) return;
    if (static_cast<int>(candidates.size()) >= limit || obs.full()) return;
    float cost = 0.0f;
    const auto hit = search_patch(rect[0].view(), p.patch, static_cast<float>(uvr.x()),
                                  static_cast<float>(uvr.y()), radius, &cost);
    candidates.push_back(id);
    if (!hit || cost > config.max_patch_cost) return;
    const std::optional<float> ur = p.far ? std::nullopt : right_u(hit->first, hit->second, depth);
    obs.push_back(
        observation_of(p, hit->first, hit->second, ur ? *ur : NAN, observation_weight(p, depth)));
    obs_point.push_back(id);
    p.tracked_frame = static_cast<std::int32_t>(frame);  // not searched twice this frame
    ++occupancy[static_cast<std::size_t>(b)];
    ++result.found;
  };
  if (only != nullptr) {
    for (const PointRef& ref : only->points) {
      if (alive(ref)) consider(ref.id);
    }
    return;
  }
  // Start at a rotating offset so every part of the map gets its turn.
  const std::size_t n = points.size();
  if (n == 0) return;
  const std::size_t start = stage2_offset % n;
  for (std::size_t k = 0; k < n && static_cast<int>(candidates.size()) < limit; ++k) {
    consider(static_cast<std::int32_t>((start + k) % n));
  }
  stage2_offset += 97;
}

/// The key-frames of this segment whose thumbnails are most like this frame's, best first.
void Tracker::Impl::rank_keyframes(std::array<const KeyframeRecord*, 8>& best, int& n) {
  make_thumbnail(rect[0].view(), thumbnail);
  const int want = std::clamp(config.relocalise_candidates, 1, static_cast<int>(best.size()));
  std::array<double, 8> ssd{};
  n = 0;
  for (const KeyframeRecord& k : keyframes) {
    if (k.id < 0 || k.segment != segment) continue;
    double d = 0.0;
    for (std::size_t i = 0; i < thumbnail.size(); ++i) {
      const double e = thumbnail[i] - k.thumbnail[i];
      d += e * e;
    }
    // Insert into the sorted short list.
    int at = n;
    while (at > 0 && ssd[static_cast<std::size_t>(at - 1)] > d) --at;
    if (at >= want) continue;
    for (int j = std::min(n, want - 1); j > at; --j) {
      best[static_cast<std::size_t>(j)] = best[static_cast<std::size_t>(j - 1)];
      ssd[static_cast<std::size_t>(j)] = ssd[static_cast<std::size_t>(j - 1)];
    }
    best[static_cast<std::size_t>(at)] = &k;
    ssd[static_cast<std::size_t>(at)] = d;
    n = std::min(n + 1, want);
  }
}

/// The frame's corners matched by descriptor to the key-frame's points, then RANSAC: works
/// away from the key-frame's pose (no prediction needed).
bool Tracker::Impl::relocalise_by_appearance(const KeyframeRecord& k, TrackResult& result) {
  if (reloc_corners.empty()) {
    // Once per lost frame: the frame's corners and their descriptors.
    std::fill(occupancy.begin(), occupancy.end(), std::uint16_t{0});
    detector.detect(rect[0].view(), occupancy, corners);
    const GrayView half = pyramid[static_cast<std::size_t>(cur_pyr)].level(1);
    for (const Corner& c : corners) {
      RelocCorner rc;
      rc.u_px = c.u_px;
      rc.v_px = c.v_px;
      rc.has_descriptor = compute_descriptor(half, c.u_px, c.v_px, rc.descriptor);
      if (rc.has_descriptor && !reloc_corners.push_back(rc)) break;
    }
  }
  if (reloc_corners.size() < static_cast<std::size_t>(config.relocalise_min_inliers)) return false;
  obs.clear();
  obs_point.clear();
  for (const PointRef& ref : k.points) {
    if (!alive(ref)) continue;
    const MapPoint& p = points[static_cast<std::size_t>(ref.id)];
    if (!p.has_descriptor) continue;
    int best = 257, second = 257;
    std::size_t best_i = 0;
    for (std::size_t i = 0; i < reloc_corners.size(); ++i) {
      const int d = hamming_distance(p.descriptor, reloc_corners[i].descriptor);
      if (d < best) {
        second = best;
        best = d;
        best_i = i;
      } else if (d < second) {
        second = d;
      }
    }
    if (best > config.relocalise_max_hamming ||
        static_cast<float>(best) >= config.relocalise_ratio * static_cast<float>(second)) {
      continue;
    }
    RelocCorner& c = reloc_corners[best_i];
    if (!c.right_tried) {
      c.right_tried = true;
      const std::optional<float> ur = right_u(c.u_px, c.v_px, -1.0);
      c.u_right_px = ur ? *ur : NAN;
    }
    if (!obs.push_back(observation_of(p, c.u_px, c.v_px, c.u_right_px, 1.0f))) break;
    obs_point.push_back(ref.id);
  }
  if (static_cast<int>(obs.size()) < config.relocalise_min_inliers) return false;
  PoseParams params = config.pose;
  params.ransac_iterations = std::max(params.ransac_iterations, 300);
  inlier.resize(obs.size());
  const PoseResult pose = estimate_pose(K, obs.span(), k.T_world_cam.inverse(), inlier.span(),
                                        static_cast<std::uint64_t>(frame) * 104729u + 3u, params);
  if (!pose.ok || pose.inliers < config.relocalise_min_inliers) return false;
  T_cw = pose.T_cam_world;
  // Descriptor matches are few: the key-frame's points found again by their patches around the
  // pose found make the tracks.
  obs.clear();
  obs_point.clear();
  for (const PointRef& ref : k.points) {
    if (alive(ref)) points[static_cast<std::size_t>(ref.id)].tracked_frame = -1;
  }
  stage2(config.stage2_radius_px, result, &k);
  if (static_cast<int>(obs.size()) < config.pose.min_inliers) return false;
  const PoseResult refined = solve(T_cw, false);
  if (!refined.ok) return false;
  T_cw = refined.T_cam_world;
  keep_inlier_tracks();
  result.inliers = refined.inliers;
  result.rms_px = refined.rms_px;
  return true;
}

/// The key-frame's points searched by their patches with a wide radius around its pose: works
/// near it (a frame that went dark or blurred without the head moving much).
bool Tracker::Impl::relocalise_by_patches(const KeyframeRecord& k, TrackResult& result) {
  T_cw = k.T_world_cam.inverse();
  obs.clear();
  obs_point.clear();
  for (const PointRef& ref : k.points) {
    if (alive(ref)) points[static_cast<std::size_t>(ref.id)].tracked_frame = -1;
  }
  stage2(config.relocalise_radius_px, result, &k);
  if (static_cast<int>(obs.size()) < config.pose.min_inliers) return false;
  const PoseResult pose = solve(T_cw, true);
  if (!pose.ok) return false;
  T_cw = pose.T_cam_world;
  keep_inlier_tracks();
  result.inliers = pose.inliers;
  result.rms_px = pose.rms_px;
  return true;
}

bool Tracker::Impl::relocalise(TrackResult& result) {
  std::array<const KeyframeRecord*, 8> best{};
  int n = 0;
  rank_keyframes(best, n);
  reloc_corners.clear();
  for (int i = 0; i < n; ++i) {
    const KeyframeRecord& k = *best[static_cast<std::size_t>(i)];
    if (relocalise_by_patches(k, result) || relocalise_by_appearance(k, result)) {
      reference_keyframe = k.id;
      return true;
    }
  }
  return false;
}

bool Tracker::Impl::need_keyframe() const {
  // Turning fast: the distance and angle rule below waits for the turn to slow down (a blurred
  // key-frame sees its points less precisely), but the tracks thinning out does not: a turn
  // into unmapped space that waits for them to run out leaves the new heading's first
  // key-frame to the turn's blurred peak with a few dozen tracks, and its error to every point
  // it makes (synth-rig quick-turns seeds 1-3: 0.4-0.9 % of the path against 0.6-1.4 %, and
  // no lost frames on eight clips; docs/results.md).
  if (turn_rate_deg_s > config.keyframe_max_turn_deg_s &&
      static_cast<double>(tracks.size()) >=
          config.keyframe_track_ratio * static_cast<double>(config.max_tracks)) {
    return false;
  }
  // Too few tracks: a key-frame adds points, but a scene with little texture would otherwise
  // make one every frame.
  if (static_cast<double>(tracks.size()) <
          config.keyframe_track_ratio * static_cast<double>(config.max_tracks) &&
      frame - last_keyframe_frame >= config.keyframe_min_frames) {
    return true;
  }
  // A quantile of the tracked points' depths sets the distance scale.
  std::array<float, 64> depths{};
  std::size_t n = 0;
  for (std::size_t i = 0; i < tracks.size() && n < depths.size();
       i += std::max<std::size_t>(1, tracks.size() / 64)) {
    depths[n++] =
        static_cast<float>((T_cw * points[static_cast<std::size_t>(tracks[i].point)].p_world).z());
  }
  if (n == 0) return true;
  const std::size_t q = std::min(
      n - 1, static_cast<std::size_t>(config.keyframe_depth_quantile * static_cast<double>(n)));
  std::nth_element(depths.begin(), depths.begin() + static_cast<std::ptrdiff_t>(q),
                   depths.begin() + static_cast<std::ptrdiff_t>(n));
  const double scene_depth = std::max(0.5, static_cast<double>(depths[q]));
  const SE3d T_wc = T_cw.inverse();
  for (const KeyframeRecord& k : keyframes) {
    if (k.id < 0 || k.segment != segment) continue;
    const double distance = (k.T_world_cam.translation() - T_wc.translation()).norm();
    const double angle = rotation_angle_deg(k.T_world_cam.linear().transpose() * T_wc.linear());
    if (distance < config.keyframe_distance_ratio * scene_depth &&
        angle < config.keyframe_angle_deg) {
      return false;  // near this key-frame
    }
  }
  return true;
}

/// Drops points that were rarely found where they were predicted; the mapper hears of it
/// through the next key-frame's message. Tracked points are kept (they were just found).
void Tracker::Impl::cull_points() {
  // Only points looked for this frame are evidence: stage 1's tracks and stage 2's candidates
  // (a point in view that was not searched says nothing about itself).
  const auto judge = [this](std::int32_t id) {
    MapPoint& p = points[static_cast<std::size_t>(id)];
    if (!p.alive) return;
    ++p.visible;
    if (p.tracked_frame == static_cast<std::int32_t>(frame)) {
      ++p.found;
      return;
    }
    if (p.visible < config.cull_after_visible ||
        static_cast<double>(p.found) >= config.cull_found_ratio * p.visible) {
      return;
    }
    if (pending_culls.full()) return;
    pending_culls.push_back(ref_of(id));
    free_point(id);
  };
  for (std::int32_t id : attempted) judge(id);
  for (std::int32_t id : candidates) judge(id);
}

void Tracker::Impl::make_keyframe(TimeNs t_ns, TrackResult& result) {
  // Points the map has in view (a place seen before) fill the buckets before new ones are made.
  if (!stage2_ran && state == TrackingState::kTracking) {
    const int found_before = result.found;
    stage2(config.stage2_radius_px, result, nullptr);
    if (result.found > found_before) {
      const PoseResult pose = solve(T_cw, false);
      if (pose.ok) {
        T_cw = pose.T_cam_world;
        keep_inlier_tracks();
        result.inliers = pose.inliers;
        result.rms_px = pose.rms_px;
      }
    }
  }
  const std::int32_t id = next_keyframe;
  message.id = id;
  message.t_ns = t_ns;
  message.T_world_cam = T_cw.inverse();
  message.segment = segment;
  message.segment_start = !segment_started;
  message.observation_sigma_px = static_cast<float>(observation_sigma_px);
  message.gyro_aided = pose_gyro_aided;
  message.observations.clear();
  message.new_points.clear();
  message.culled.clear();
  for (const PointRef& point : pending_culls) message.culled.push_back(point);
  pending_culls.clear();
  for (const Track& t : tracks) {
    message.observations.push_back(
        KeyframeObservation{t.point, points[static_cast<std::size_t>(t.point)].generation, t.u_px,
                            t.v_px, t.u_right_px});
  }
  bool map_full = false;
  result.new_points = add_stereo_points(map_full);
  result.map_full = map_full;
  KeyframeRecord& k = record_for_new_keyframe();
  k.id = id;
  k.t_ns = t_ns;
  k.T_world_cam = message.T_world_cam;
  k.segment = segment;
  k.points.clear();
  for (const KeyframeObservation& o : message.observations) {
    k.points.push_back(PointRef{o.point, o.generation});
    MapPoint& p = points[static_cast<std::size_t>(o.point)];
    if (p.observations < 65535) ++p.observations;
  }
  make_thumbnail(rect[0].view(), k.thumbnail);
  reference_keyframe = id;
  ++next_keyframe;
  last_keyframe_frame = frame;
  segment_started = true;
  message_pending = true;
  result.keyframe = true;
}

/// The first key-frame of a segment, at the current pose (the identity for the first map).
void Tracker::Impl::initialise(TimeNs t_ns, TrackResult& result) {
  tracks.clear();
  const std::int32_t first_id = next_keyframe;
  make_keyframe(t_ns, result);
  if (result.new_points < config.min_initial_points) {
    // Not enough structure (blank wall, dark frame): forget this attempt, try the next frame.
    if (KeyframeRecord* k = keyframe_by_id(first_id)) k->id = -1;
    for (const NewMapPoint& p : message.new_points) free_point(p.point);
    next_keyframe = first_id;
    reference_keyframe = -1;
    segment_started = false;
    tracks.clear();
    message_pending = false;
    result.keyframe = false;
    result.new_points = 0;
    result.map_full = false;
    return;
  }
  state = TrackingState::kTracking;
  result.inliers = result.new_points;
}

TrackResult Tracker::track(TimeNs t_ns, const Image& left, const Image& right,
                           const RotationPrior& gyro) {
  Impl& m = *impl_;
  TrackResult result;
  result.t_ns = t_ns;
  result.stale_updates = m.stale_updates;
  m.stale_updates = 0;
  const std::int64_t t0 = m.now();
  m.message_pending = false;
  result.rejected = m.check(left, right);
  if (result.rejected != nullptr) {
    result.frame = m.frame;
    result.state = m.state;
    result.segment = m.segment;
    result.T_world_cam = m.T_cw.inverse();
    return result;
  }
  m.rectify(left, right);
  const std::int64_t t1 = m.now();
  ++m.frame;
  result.frame = m.frame;
  m.cur_pyr = 1 - m.cur_pyr;
  m.pyramid[static_cast<std::size_t>(m.cur_pyr)].build(m.rect[0].view());
  const std::int64_t t2 = m.now();
  std::int64_t t3 = t2, t4 = t2;
  m.stage2_ran = false;
  m.pose_gyro_aided = false;

  if (m.state == TrackingState::kInitialising) {
    m.initialise(t_ns, result);
    t3 = t4 = m.now();
  } else {
    // Prediction: constant velocity, with the gyro's rotation when given, and with the
    // accelerometer's specific force the centre through the head's accelerations.
    const double dt_s = m.last_t_ns > 0 && t_ns > m.last_t_ns ? ns_to_s(t_ns - m.last_t_ns) : 0.0;
    SE3d prior = predict_camera_pose(m.T_cw, m.velocity, gyro);
    if (gyro.valid && m.config.accel_prediction) m.predict_centre(gyro, dt_s, prior);
    m.gyro_prior_valid = gyro.valid && gyro.bias_corrected;
    // The turn rate this frame (the prediction's: the gyro's when it has one).
    m.turn_rate_deg_s =
        dt_s > 0.0 ? rotation_angle_deg(prior.linear() * m.T_cw.linear().transpose()) / dt_s : 0.0;
    m.observation_sigma_px =
        1.0 + m.config.blur_sigma_px_per_deg_s *
                  std::max(0.0, m.turn_rate_deg_s - m.config.keyframe_max_turn_deg_s);
    m.gyro_R_cw = prior.linear();
    m.gyro_sigma_deg = gyro_prior_sigma_deg(m.config, dt_s);
    bool ok = false;
    if (m.state == TrackingState::kTracking) {
      m.stage1(prior, result);
      PoseResult pose;
      if (!m.obs.empty()) pose = m.solve(prior, true);
      t3 = m.now();
      if (pose.ok) m.T_cw = pose.T_cam_world;
      // Stage 2 when the tracks thin out (or stage 1 failed): re-find map points by patch.
      if (!pose.ok || pose.inliers < static_cast<int>(0.8 * m.config.max_tracks)) {
        if (!pose.ok) m.T_cw = prior;
        m.stage2(m.config.stage2_radius_px, result, nullptr);
        if (!m.obs.empty()) pose = m.solve(m.T_cw, !pose.ok);
      }
      if (!pose.ok && !m.velocity.isApprox(SE3d::Identity())) {
        // The motion model may be what failed (the head stopped or turned back): once more from
        // the last pose, turned as the gyro says.
        const SE3d still =
            gyro.valid ? predict_camera_pose(m.T_cw_last, SE3d::Identity(), gyro) : m.T_cw_last;
        m.stage1(still, result);
        if (!m.obs.empty()) pose = m.solve(still, true);
      }
      if (pose.ok) {
        m.T_cw = pose.T_cam_world;
        m.keep_inlier_tracks();
        result.inliers = pose.inliers;
        result.rms_px = pose.rms_px;
        m.pose_gyro_aided = m.gyro_prior_active();
        ok = true;
      }
      t4 = m.now();
    }
    m.gyro_prior_valid = false;  // relocalisation and key-frames: vision alone
    if (!ok) {
      // Lost: relocalise against the key-frames; meanwhile the motion model carries the pose
      // on for a few frames, then holds it (never NaN).
      const SE3d carried = m.lost_frames < m.config.lost_extrapolate_frames ? prior : m.T_cw_last;
      if (m.relocalise(result)) {
        ok = true;
        result.relocalised = true;
      } else {
        m.T_cw = carried;
        m.tracks.clear();
      }
      t3 = t4 = m.now();
    }
    if (ok && gyro.valid && gyro.accel_valid && m.state == TrackingState::kTracking &&
        !result.relocalised) {
      m.learn_gravity(gyro, dt_s);
      m.accel_last = true;
      m.last_force = SpecificForceInterval{gyro.dv_imu_m_s, gyro.dp_imu_m, dt_s};
    } else {
      m.accel_last = false;
    }
    if (ok) {
      m.state = TrackingState::kTracking;
      m.velocity = orthonormalised(m.T_cw * m.T_cw_last.inverse());
      m.lost_frames = 0;
      m.cull_points();
      if (m.need_keyframe()) {
        if (m.keyframes_allowed) {
          m.make_keyframe(t_ns, result);
        } else {
          result.keyframe_deferred = true;
        }
      }
    } else {
      m.state = TrackingState::kLost;
      ++m.lost_frames;
      if (m.lost_frames > m.config.lost_extrapolate_frames) m.velocity = SE3d::Identity();
      if (m.config.new_segment_after_lost > 0 && m.lost_frames >= m.config.new_segment_after_lost &&
          m.keyframes_allowed) {
        // Relocalisation keeps failing: a new map segment from this frame's stereo points at
        // the pose carried on so far. The old segment's points stay in the map (its walls), but
        // tracking and relocalisation use the new one's.
        ++m.segment;
        m.segment_started = false;
        m.tracks.clear();
        m.reference_keyframe = -1;
        m.initialise(t_ns, result);
        if (m.state == TrackingState::kTracking) {
          result.new_segment = true;
          m.lost_frames = 0;
          m.velocity = SE3d::Identity();
        } else {
          --m.segment;  // nothing to start from yet (a dark frame): try again next frame
          m.state = TrackingState::kLost;
        }
      }
    }
  }
  m.T_cw_before = m.T_cw_last;
  m.T_cw_last = m.T_cw;
  m.last_t_ns = t_ns;
  const std::int64_t t5 = m.now();
  result.state = m.state;
  result.segment = m.segment;
  result.T_world_cam = m.T_cw.inverse();
  result.times = TrackerTimes{t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4, t5 - t0};
  return result;
}

void Tracker::apply(const MapCorrection& correction) {
  Impl& m = *impl_;
  for (const MapCorrection::Point& c : correction.points) {
    if (!m.alive(PointRef{c.point, c.generation})) {
      // Culled (and perhaps reused) since the mapper saw it: the correction is for a point
      // that no longer exists.
      if (c.point >= 0) ++m.stale_updates;
      continue;
    }
    if (!c.p_world.allFinite()) continue;
    MapPoint& p = m.points[static_cast<std::size_t>(c.point)];
    p.p_world = c.p_world;
    p.sigma_m = c.sigma_m;
  }
  for (const PointRef& ref : correction.culled) {
    if (!m.alive(ref)) {
      if (ref.id >= 0) ++m.stale_updates;
      continue;
    }
    m.free_point(ref.id);
  }
  for (const MapCorrection::Keyframe& c : correction.keyframes) {
    KeyframeRecord* k = m.keyframe_by_id(c.id);
    if (k == nullptr || !c.T_world_cam.matrix().allFinite()) continue;
    if (c.id == m.reference_keyframe) {
      // The camera keeps its pose relative to its reference key-frame.
      const SE3d shift = c.T_world_cam * k->T_world_cam.inverse();  // old world -> new world
      m.T_cw = orthonormalised(m.T_cw * shift.inverse());
      m.T_cw_last = orthonormalised(m.T_cw_last * shift.inverse());
      m.T_cw_before = orthonormalised(m.T_cw_before * shift.inverse());
      m.gravity.rotate(shift.linear());
    }
    k->T_world_cam = c.T_world_cam;
  }
  for (std::int32_t id : correction.culled_keyframes) {
    if (KeyframeRecord* k = m.keyframe_by_id(id)) k->id = -1;
    if (id == m.reference_keyframe) m.reference_keyframe = -1;
  }
}

}  // namespace wallar::dsp
