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
#include <vector>

#include "wallar/core/point_cloud.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/dsp/tracking/stereo_camera.hpp"
#include "wallar/dsp/tracking/tracker.hpp"

namespace wallar::dsp {

struct MapperConfig {
  int local_keyframes = 6;       //!< key-frames moved by a local adjustment
  int local_iterations = 6;
  int global_iterations = 10;
  double huber_px = 1.5;
  double cull_error_px = 4.0;    //!< mean reprojection error above which a point is culled
  int min_keyframes_for_ba = 2;
};

/// The sparse map, published as one consistent value.
struct MapSnapshot {
  std::uint64_t version = 0;
  PointCloud points;                      //!< world frame; observations = key-frames that saw it
  std::vector<float> sigma_m;             //!< per point, position uncertainty (1 sigma)
  std::vector<std::int32_t> point_ids;    //!< the tracker's id of each point
  std::vector<Eigen::Vector3d> keyframe_centres;  //!< camera centres of the key-frames
  std::vector<TimeNs> keyframe_t_ns;
  /// Which key-frames saw point i: viewer_index[viewer_offset[i] .. viewer_offset[i + 1]).
  std::vector<std::uint32_t> viewer_offset;
  std::vector<std::uint32_t> viewer_index;
};

struct MapperStats {
  int keyframes = 0;
  int points = 0;
  int adjusted_keyframes = 0;
  int adjusted_points = 0;
  int iterations = 0;
  int culled = 0;
  double initial_cost = 0.0, final_cost = 0.0;
};

class Mapper {
 public:
  Mapper(const StereoIntrinsics& K, const MapperConfig& config = {});
  ~Mapper();
  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;

  /// Stores a key-frame, its observations and its new points.
  void add_keyframe(const KeyframeMessage& message);
  /// Bundle adjustment of the last local_keyframes key-frames and the points they saw (older
  /// key-frames that saw those points hold still); culls points that do not fit. Writes the
  /// moved points and key-frames into `out` (cleared first, filled until full).
  MapperStats local_adjust(MapCorrection& out);
  /// Bundle adjustment of every key-frame (the first holds still): for idle time.
  MapperStats global_adjust(MapCorrection& out);
  [[nodiscard]] MapSnapshot snapshot() const;
  [[nodiscard]] int keyframe_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wallar::dsp
