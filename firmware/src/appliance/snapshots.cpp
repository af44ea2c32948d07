// SPDX-License-Identifier: Apache-2.0
/// @file snapshots.cpp
/// @brief The pose snapshot, packed and unpacked.
#include "wallar/firmware/appliance/snapshots.hpp"

namespace wallar::firmware {

PoseSnapshot make_pose_snapshot(TimeNs t_ns, const SE3d& T, dsp::TrackingState state,
                                const std::optional<Eigen::Vector3d>& down, std::uint32_t epoch,
                                bool imu_only) {
  PoseSnapshot s;
  s.t_ns = t_ns;
  Eigen::Map<Eigen::Matrix3d>(s.R) = T.linear();
  Eigen::Map<Eigen::Vector3d>(s.p) = T.translation();
  if (down) {
    Eigen::Map<Eigen::Vector3d>(s.down_world) = *down;
    s.has_down = true;
  }
  s.epoch = epoch;
  s.state = static_cast<std::uint8_t>(state);
  s.imu_only = imu_only;
  return s;
}

std::optional<Eigen::Vector3d> down_of(const PoseSnapshot& s) {
  if (!s.has_down) return std::nullopt;
  return Eigen::Vector3d(s.down_world[0], s.down_world[1], s.down_world[2]);
}

}  // namespace wallar::firmware
