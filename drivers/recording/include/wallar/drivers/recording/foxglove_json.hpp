// SPDX-License-Identifier: Apache-2.0
/// @file foxglove_json.hpp
/// @brief The building blocks of Foxglove's JSON messages: its time ({sec, nsec}), Vector3
/// ({x, y, z}) and Quaternion ({x, y, z, w}), for the recording's own messages and the
/// firmware's outputs (firmware/foxglove_messages.hpp) alike.
///
/// Threading: pure functions.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "wallar/core/time.hpp"

namespace wallar::recording::foxglove_json {

/// A non-negative time in ns as Foxglove's {sec, nsec}.
inline nlohmann::json time(TimeNs t_ns) {
  return {{"sec", t_ns / kNsPerS}, {"nsec", t_ns % kNsPerS}};
}
inline nlohmann::json vector3(const Eigen::Vector3d& v) {
  return {{"x", v.x()}, {"y", v.y()}, {"z", v.z()}};
}
inline nlohmann::json quaternion(const Eigen::Quaterniond& q) {
  return {{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}};
}

}  // namespace wallar::recording::foxglove_json
