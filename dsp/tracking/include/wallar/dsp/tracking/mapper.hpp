// SPDX-License-Identifier: Apache-2.0
/// @file mapper.hpp
/// @brief The mapping half of tracking and mapping: keeps every key-frame and map point the
/// tracker made, runs local bundle adjustment over the last key-frames after each new one and
/// global bundle adjustment when idle, culls points that do not fit, and hands corrections back
/// to the tracker (Tracker::apply) and a map snapshot to the wall finder.
///
/// The mapper may allocate (it is outside the fixed-rate path); it never blocks the tracker,
/// which talks to it only through messages (KeyframeMessage in, MapCorrection out).
///
/// Threading: one thread owns a Mapper (the mapping thread, or the tracker's caller when run
/// in lock step). Snapshots are values and may be handed to any thread.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "wallar/core/point_cloud.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/dsp/tracking/stereo_camera.hpp"
#include "wallar/dsp/tracking/tracker.hpp"

namespace wallar::dsp {

struct MapperConfig {
  int local_keyframes = 6;  //!< key-frames moved by a local adjustment
  /// Key-frames outside the window that see its points and hold still in a local adjustment:
  /// at most this many (the ones sharing the most points), so a place seen from many
  /// key-frames does not make each adjustment slower.
  int local_fixed_keyframes = 12;
  int local_iterations = 6;
  int global_iterations = 10;
  /// A global adjustment moves at most this many key-frames (the newest), holding the ones
  /// that share points with them still: bounded time however long the headset runs.
  int global_keyframes = 48;
  double huber_px = 1.5;
  /// A key-frame an adjustment moves is held near its tracked pose with these spreads, plus
  /// the per-metre growth times its distance from the key-frame before (the tracker's pose is
  /// information too: it keeps a key-frame that shares few points from sliding along what they
  /// leave unconstrained; tracked farther, it is trusted less).
  double keyframe_prior_m = 0.02, keyframe_prior_deg = 0.2;
  double keyframe_prior_m_per_m = 0.05, keyframe_prior_deg_per_m = 0.3;
  /// The rotation spreads for a key-frame tracked with the gyro (KeyframeMessage::gyro_aided).
  /// A head turning on the spot makes key-frames whose views share few points, so the points
  /// hold their relative rotations loosely; the gyro knows them to a few hundredths of a
  /// degree. Held at the vision-only spreads, local adjustments turned such key-frames by
  /// 0.5-0.8 deg and their points 1-7 cm (synth-rig quick turns, seed 4: ATE 2.3 cm); held at
  /// these, 0.6 cm on that clip and 0.4-0.7 cm on seeds 1-6 (docs/results.md, issue 17).
  double keyframe_prior_deg_gyro = 0.04, keyframe_prior_deg_per_m_gyro = 0.06;
  double cull_error_px = 4.0;  //!< mean reprojection error above which a point is culled
  int min_keyframes_for_ba = 2;
  /// A key-frame is redundant when this share of its points is seen by at least
  /// redundant_observers other key-frames (ORB-SLAM's rule); it is dropped, its points kept.
  double redundant_share = 0.9;
  int redundant_observers = 3;
  int keep_newest_keyframes = 4;  //!< never dropped (tracking still refers to them)
  /// A point no other key-frame saw by the time this many more key-frames were made is
  /// dropped (0: never).
  int confirm_keyframes = 3;
};

/// The sparse map, published as one consistent value.
struct MapSnapshot {
  std::uint64_t version = 0;
  PointCloud points;                    //!< world frame; observations = key-frames that saw it
  std::vector<float> sigma_m;           //!< per point, position uncertainty (1 sigma)
  std::vector<std::int32_t> point_ids;  //!< the tracker's id of each point
  std::vector<Eigen::Vector3d> keyframe_centres;  //!< camera centres of the key-frames
  /// Each key-frame's image-down direction (its camera's +y axis) in the world.
  std::vector<Eigen::Vector3d> keyframe_image_down;
  std::vector<TimeNs> keyframe_t_ns;
  /// Which key-frames saw point i: viewer_index[viewer_offset[i] .. viewer_offset[i + 1]).
  std::vector<std::uint32_t> viewer_offset;
  std::vector<std::uint32_t> viewer_index;
};

struct MapperStats {
  int keyframes = 0;  //!< key-frames in the map (dropped ones not counted)
  int points = 0;
  int culled_keyframes = 0;  //!< dropped as redundant by this adjustment
  int adjusted_keyframes = 0;
  int adjusted_points = 0;
  int iterations = 0;
  int culled = 0;
  double initial_cost = 0.0, final_cost = 0.0;
};

/// Down from the path alone (no IMU): a rig carried over the ground (walking, driving) keeps
/// its centres near one horizontal plane. When the key-frame centres spread over more than
/// `min_extent_m` in two directions and less than `max_flatness` of that in the third, the
/// plane's normal, on the side the key-frames' image-down axes point to, is down. Otherwise
/// (a head standing in a room, a path along one line) nothing.
std::optional<Eigen::Vector3d> down_from_path(const MapSnapshot& map, double min_extent_m = 3.0,
                                              double max_flatness = 0.1);

/// The part of the map around the newest key-frame that the wall search looks at: points
/// within radius_m of its centre, the key-frames there as viewpoints, and the points' median
/// position uncertainty. A room fits in it whole; on a street it is the stretch around the rig
/// (a 139 m drive's facades are no room: planes from one street would be "seen from behind"
/// by the key-frames around the corner).
/// `out` keeps its capacity from call to call.
struct LocalMap {
  PointCloud points;
  std::vector<Eigen::Vector3d> viewpoints;
  double median_sigma_m = 0.0;
  std::vector<float> sigma_scratch;  //!< working space (the points' sigmas, reordered)
};
void local_map(const MapSnapshot& map, double radius_m, LocalMap& out);

class Mapper {
 public:
  Mapper(const StereoIntrinsics& K, const MapperConfig& config = {});
  ~Mapper();
  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;

  /// Stores a key-frame, its observations and its new points. Culls and observations naming a
  /// generation of a point other than the one the map holds are ignored (counted).
  void add_keyframe(const KeyframeMessage& message);
  /// Bundle adjustment of the last local_keyframes key-frames and the points they saw (older
  /// key-frames that saw those points hold still); culls points that do not fit. Writes the
  /// moved points and key-frames into `out` (cleared first, filled until full).
  MapperStats local_adjust(MapCorrection& out);
  /// Bundle adjustment of the newest global_keyframes key-frames (each segment's first holds
  /// still, and the older ones that share points with them): for idle time.
  MapperStats global_adjust(MapCorrection& out);
  [[nodiscard]] MapSnapshot snapshot() const;
  [[nodiscard]] int keyframe_count() const;              //!< in the map now
  [[nodiscard]] int points_count() const;                //!< alive points
  [[nodiscard]] std::uint64_t culled_keyframes() const;  //!< dropped as redundant, in all
  [[nodiscard]] std::uint64_t stale_messages() const;    //!< parts naming an old generation

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wallar::dsp
