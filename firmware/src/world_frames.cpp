// SPDX-License-Identifier: Apache-2.0
/// @file world_frames.cpp
/// @brief Rigid changes of frame for walls and clouds.
#include "wallar/firmware/world_frames.hpp"

namespace wallar::firmware {

Wall transformed(const Wall& wall, const SE3d& T_new_old) {
  Wall w = wall;
  const Eigen::Matrix3d R = T_new_old.linear();
  w.plane.n = R * wall.plane.n;
  w.plane.d = wall.plane.d + w.plane.n.dot(T_new_old.translation());
  w.origin = T_new_old * wall.origin;
  w.u = R * wall.u;
  w.v = R * wall.v;
  return w;
}

WallModel transformed(const WallModel& model, const SE3d& T_new_old) {
  WallModel out = model;
  for (Wall& w : out.walls) w = transformed(w, T_new_old);
  return out;
}

dsp::RoomResult transformed(const dsp::RoomResult& room, const SE3d& T_new_old) {
  dsp::RoomResult out = room;
  out.model = transformed(room.model, T_new_old);
  for (dsp::RoomSurface& s : out.surfaces) s.wall = transformed(s.wall, T_new_old);
  return out;
}

PointCloud transformed(const PointCloud& cloud, const SE3d& T_new_old) {
  PointCloud out;
  out.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    out.push_back((T_new_old * cloud.point(i).cast<double>()).cast<float>());
  }
  out.weight = cloud.weight;
  out.observations = cloud.observations;
  return out;
}

}  // namespace wallar::firmware
