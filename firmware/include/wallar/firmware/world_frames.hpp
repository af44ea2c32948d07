// SPDX-License-Identifier: Apache-2.0
/// @file world_frames.hpp
/// @brief Walls, wall models, room results and point clouds expressed in another frame, by
/// the rigid transform T_new_old (maps old coordinates into new): the appliance works in the
/// tracker's world, the commands write their files in the first body pose's (or gravity's).
///
/// Planes n.p - d = 0 become n' = R n, d' = d + n'.t; extents keep their (u, v) coordinates
/// with the basis and origin moved along.
///
/// Threading: pure functions.
#pragma once

#include "wallar/core/point_cloud.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/dsp/walls/room.hpp"

namespace wallar::firmware {

Wall transformed(const Wall& wall, const SE3d& T_new_old);
WallModel transformed(const WallModel& model, const SE3d& T_new_old);
dsp::RoomResult transformed(const dsp::RoomResult& room, const SE3d& T_new_old);
/// The points moved (float, as stored), their optional columns kept.
PointCloud transformed(const PointCloud& cloud, const SE3d& T_new_old);

}  // namespace wallar::firmware
