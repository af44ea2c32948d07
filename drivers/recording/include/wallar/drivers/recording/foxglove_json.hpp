// SPDX-License-Identifier: Apache-2.0
/// @file foxglove_json.hpp
/// @brief The building blocks of Foxglove's JSON messages: its time ({sec, nsec}), Vector3
/// ({x, y, z}) and Quaternion ({x, y, z, w}), and the schemas both sides use (time,
/// CompressedImage), for the recording's own messages and the firmware's outputs
/// (firmware/foxglove_messages.hpp) alike.
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

/// JSON Schema of Foxglove's time.
inline nlohmann::json time_schema() {
  return {{"type", "object"},
          {"title", "time"},
          {"properties",
           {{"sec", {{"type", "integer"}, {"minimum", 0}}},
            {"nsec", {{"type", "integer"}, {"minimum", 0}, {"maximum", 999999999}}}}}};
}

/// Foxglove's CompressedImage, as its published JSON Schema describes it (the recording's PNG
/// images and the live server's JPEG ones).
inline nlohmann::json compressed_image_schema() {
  return {
      {"title", "foxglove.CompressedImage"},
      {"description", "A compressed image"},
      {"type", "object"},
      {"properties",
       {{"timestamp", time_schema()},
        {"frame_id", {{"type", "string"}, {"description", "Frame of reference for the image"}}},
        {"data",
         {{"type", "string"}, {"contentEncoding", "base64"}, {"description", "Compressed image"}}},
        {"format", {{"type", "string"}, {"description", "Image format: jpeg or png"}}}}},
      {"required", {"timestamp", "frame_id", "data", "format"}}};
}

}  // namespace wallar::recording::foxglove_json
