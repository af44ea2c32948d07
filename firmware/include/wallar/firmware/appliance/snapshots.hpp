// SPDX-License-Identifier: Apache-2.0
/// @file snapshots.hpp
/// @brief The values of the appliance's snapshot channels: the pose (a Seqlock of a trivially
/// copyable record: pose, gravity in the world, reset epoch) and the map (a TripleBuffer of
/// shared, immutable map snapshots). The wall model's channel carries a WallModel.
///
/// Threading: plain values and pure functions.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include "wallar/core/pose.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/tracking/tracker.hpp"

namespace wallar::firmware {

/// The pose channel's value (trivially copyable for the seqlock).
struct PoseSnapshot {
  TimeNs t_ns = 0;
  double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  // column-major R_world_body
  double p[3] = {0, 0, 0};
  double down_world[3] = {0, 0, 0};
  std::uint32_t epoch = 0;  //!< +1 at each reset (the map restarts)
  std::uint8_t state = 0;
  bool has_down = false;
  bool imu_only = false;
};

PoseSnapshot make_pose_snapshot(TimeNs t_ns, const SE3d& T_world_body, dsp::TrackingState state,
                                const std::optional<Eigen::Vector3d>& down, std::uint32_t epoch,
                                bool imu_only);
/// Gravity's direction in the world, when the snapshot has it.
std::optional<Eigen::Vector3d> down_of(const PoseSnapshot& s);

using MapPtr = std::shared_ptr<const dsp::MapSnapshot>;

}  // namespace wallar::firmware
