// SPDX-License-Identifier: Apache-2.0
/// @file foxglove_messages.hpp
/// @brief The firmware's outputs as Foxglove messages (JSON, under Foxglove's published schema
/// names, so Foxglove's 3-D panel draws them): the head pose (foxglove.PoseInFrame), the body
/// frame (foxglove.FrameTransform world -> body), the sparse map (foxglove.PointCloud: x, y, z,
/// sigma as float32, coloured by surface where a point lies on one) and the walls, floor and
/// ceiling (foxglove.SceneUpdate: each surface's extent as a triangle list in its colour, its
/// outline and a label), the trajectory (foxglove.PosesInFrame), camera images
/// (foxglove.CompressedImage), log lines (foxglove.Log) and the stats table (wallar.Stats: the
/// threads and stages of `wallar run --stats`). For MCAP files (`wallar track --mcap`) and the
/// live server (`wallar run --live`) alike.
///
/// Threading: pure functions.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "wallar/core/point_cloud.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/firmware/appliance/records.hpp"

namespace wallar::firmware::foxglove {

/// One channel's schema: Foxglove's name and a JSON Schema of the fields written.
struct Schema {
  const char* name;
  std::string json_schema;
};
Schema pose_in_frame_schema();
Schema frame_transform_schema();
Schema point_cloud_schema();
Schema scene_update_schema();
Schema frame_transforms_schema();
Schema poses_in_frame_schema();
Schema compressed_image_schema();
Schema log_schema();
/// wallar.Stats: {timestamp, threads: [...], stages: [...], live: {...}}, each row as
/// `wallar run --json` writes it.
Schema stats_schema();

/// T_world_body at t_ns, in frame "world".
std::string pose_in_frame(TimeNs t_ns, const SE3d& T_world_body);
/// The transform `parent` -> `child` (e.g. world -> body, body -> cam0).
std::string frame_transform(TimeNs t_ns, const SE3d& T_parent_child, const std::string& child,
                            const std::string& parent = "world");
/// The map in frame "world": x, y, z and sigma (m) per point, with the colour (r, g, b as
/// float32 in 0-1) of the surface whose inlier band holds it (grey otherwise).
std::string point_cloud(TimeNs t_ns, const PointCloud& map, const std::vector<float>& sigma_m,
                        const std::vector<Wall>& walls);
/// Every surface as one entity "surface-ID" (replacing the one of that id): the extent as
/// triangles, its outline, and "wall 3" style labels. With `replace_all` the update first
/// deletes every entity it did not name (a live model: surfaces merged or reset go away).
std::string scene_update(TimeNs t_ns, const std::vector<Wall>& walls, bool replace_all = false);
/// One transform of a foxglove.FrameTransforms: `T_parent_child` maps child into parent.
struct NamedTransform {
  const char* parent;
  const char* child;
  SE3d T_parent_child;
};
/// Several transforms in one message (one channel carries the whole tree, newest wins).
std::string frame_transforms(TimeNs t_ns, const std::vector<NamedTransform>& transforms);
/// The body's path in frame "world" (oldest first).
std::string poses_in_frame(TimeNs t_ns, std::span<const SE3d> T_world_body);
/// An encoded image (`format` "jpeg" or "png") in frame `frame_id`.
std::string compressed_image(TimeNs t_ns, const std::string& frame_id, const char* format,
                             std::span<const std::uint8_t> data);
/// foxglove.Log's levels.
enum class LogLevel : std::uint8_t { kDebug = 1, kInfo = 2, kWarning = 3, kError = 4, kFatal = 5 };
/// One log line from `name` (the firmware: "wallar").
std::string log(TimeNs t_ns, LogLevel level, const std::string& message, const std::string& name);
/// The stats message: the rows as `wallar run --json` writes them, and the live server's
/// counters (name, value) as the object `live`.
std::string stats(TimeNs t_ns, const std::vector<ThreadRow>& threads,
                  const std::vector<StageRow>& stages,
                  const std::vector<std::pair<const char*, std::uint64_t>>& live);

}  // namespace wallar::firmware::foxglove
