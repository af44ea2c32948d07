// SPDX-License-Identifier: Apache-2.0
/// @file foxglove_messages.hpp
/// @brief The firmware's outputs as Foxglove messages (JSON, under Foxglove's published schema
/// names, so Foxglove's 3-D panel draws them): the head pose (foxglove.PoseInFrame), the body
/// frame (foxglove.FrameTransform world -> body), the sparse map (foxglove.PointCloud: x, y, z,
/// sigma as float32, coloured by surface where a point lies on one) and the walls, floor and
/// ceiling (foxglove.SceneUpdate: each surface's extent as a triangle list in its colour, its
/// outline and a label). For MCAP files (`wallar track --mcap`) and a live server alike.
///
/// Threading: pure functions.
#pragma once

#include <string>
#include <vector>

#include "wallar/core/point_cloud.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/time.hpp"
#include "wallar/core/wall.hpp"

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

/// T_world_body at t_ns, in frame "world".
std::string pose_in_frame(TimeNs t_ns, const SE3d& T_world_body);
/// The transform world -> `child` (e.g. "body").
std::string frame_transform(TimeNs t_ns, const SE3d& T_world_child, const std::string& child);
/// The map in frame "world": x, y, z and sigma (m) per point, with the colour (r, g, b as
/// float32 in 0-1) of the surface whose inlier band holds it (grey otherwise).
std::string point_cloud(TimeNs t_ns, const PointCloud& map, const std::vector<float>& sigma_m,
                        const std::vector<Wall>& walls);
/// Every surface as one entity "surface-ID" (replacing the one of that id): the extent as
/// triangles, its outline, and "wall 3" style labels.
std::string scene_update(TimeNs t_ns, const std::vector<Wall>& walls);

}  // namespace wallar::firmware::foxglove
