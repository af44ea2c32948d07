// SPDX-License-Identifier: Apache-2.0
/// @file foxglove_messages.cpp
/// @brief Foxglove JSON messages of the firmware's outputs (see foxglove_messages.hpp).
#include "wallar/firmware/foxglove_messages.hpp"

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

#include "wallar/drivers/recording/foxglove_json.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/firmware/appliance/stats.hpp"

namespace wallar::firmware::foxglove {
namespace {

using nlohmann::json;
namespace fj = recording::foxglove_json;

constexpr double kOnSurfaceM = 0.1;  // a map point this near a surface's plane takes its colour
constexpr int kFloat32 = 7;          // foxglove.NumericType FLOAT32

json pose(const SE3d& T) {
  return {{"position", fj::vector3(T.translation())},
          {"orientation", fj::quaternion(Eigen::Quaterniond(T.linear()).normalized())}};
}
json colour(std::uint32_t id, double alpha) {
  const auto c = surface_colour_rgb(id);
  return {{"r", c[0] / 255.0}, {"g", c[1] / 255.0}, {"b", c[2] / 255.0}, {"a", alpha}};
}

// JSON Schema pieces, named as Foxglove names them.
json number() { return {{"type", "number"}}; }
json object(const char* title, json properties) {
  return {{"title", title}, {"type", "object"}, {"properties", std::move(properties)}};
}
json vector3_schema() {
  return object("foxglove.Vector3", {{"x", number()}, {"y", number()}, {"z", number()}});
}
json point3_schema() {
  return object("foxglove.Point3", {{"x", number()}, {"y", number()}, {"z", number()}});
}
json quaternion_schema() {
  return object("foxglove.Quaternion",
                {{"x", number()}, {"y", number()}, {"z", number()}, {"w", number()}});
}
json pose_schema() {
  return object("foxglove.Pose",
                {{"position", vector3_schema()}, {"orientation", quaternion_schema()}});
}
json color_schema() {
  return object("foxglove.Color",
                {{"r", number()}, {"g", number()}, {"b", number()}, {"a", number()}});
}
json array_of(json items) { return {{"type", "array"}, {"items", std::move(items)}}; }
json string_schema() { return {{"type", "string"}}; }

// The extent polygon's corners in world coordinates.
std::vector<Eigen::Vector3d> corners(const Wall& w) {
  std::vector<Eigen::Vector3d> c;
  for (std::size_t i = 0; i < w.extent_uv_m.size(); ++i) c.push_back(w.corner(i));
  return c;
}

// Whether (u, v) lies inside the convex polygon (either winding).
bool inside_convex(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p) {
  if (poly.size() < 3) return false;
  int sign = 0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d a = poly[i];
    const Eigen::Vector2d b = poly[(i + 1) % poly.size()];
    const double cross = (b - a).x() * (p - a).y() - (b - a).y() * (p - a).x();
    const int s = cross > 0.0 ? 1 : (cross < 0.0 ? -1 : 0);
    if (s == 0) continue;
    if (sign == 0) sign = s;
    if (s != sign) return false;
  }
  return true;
}

}  // namespace

Schema pose_in_frame_schema() {
  return {"foxglove.PoseInFrame", object("foxglove.PoseInFrame", {{"timestamp", fj::time_schema()},
                                                                  {"frame_id", string_schema()},
                                                                  {"pose", pose_schema()}})
                                      .dump()};
}

Schema frame_transform_schema() {
  return {"foxglove.FrameTransform",
          object("foxglove.FrameTransform", {{"timestamp", fj::time_schema()},
                                             {"parent_frame_id", string_schema()},
                                             {"child_frame_id", string_schema()},
                                             {"translation", vector3_schema()},
                                             {"rotation", quaternion_schema()}})
              .dump()};
}

Schema point_cloud_schema() {
  const json field = object("foxglove.PackedElementField",
                            {{"name", string_schema()},
                             {"offset", {{"type", "integer"}, {"minimum", 0}}},
                             {"type", {{"type", "integer"}, {"description", "7 = FLOAT32"}}}});
  return {
      "foxglove.PointCloud",
      object("foxglove.PointCloud", {{"timestamp", fj::time_schema()},
                                     {"frame_id", string_schema()},
                                     {"pose", pose_schema()},
                                     {"point_stride", {{"type", "integer"}, {"minimum", 0}}},
                                     {"fields", array_of(field)},
                                     {"data", {{"type", "string"}, {"contentEncoding", "base64"}}}})
          .dump()};
}

Schema scene_update_schema() {
  const json triangles =
      object("foxglove.TriangleListPrimitive", {{"pose", pose_schema()},
                                                {"points", array_of(point3_schema())},
                                                {"color", color_schema()},
                                                {"colors", array_of(color_schema())},
                                                {"indices", array_of({{"type", "integer"}})}});
  const json line = object("foxglove.LinePrimitive",
                           {{"type", {{"type", "integer"}, {"description", "1 = LINE_LOOP"}}},
                            {"pose", pose_schema()},
                            {"thickness", number()},
                            {"scale_invariant", {{"type", "boolean"}}},
                            {"points", array_of(point3_schema())},
                            {"color", color_schema()},
                            {"colors", array_of(color_schema())},
                            {"indices", array_of({{"type", "integer"}})}});
  const json text = object("foxglove.TextPrimitive", {{"pose", pose_schema()},
                                                      {"billboard", {{"type", "boolean"}}},
                                                      {"font_size", number()},
                                                      {"scale_invariant", {{"type", "boolean"}}},
                                                      {"color", color_schema()},
                                                      {"text", string_schema()}});
  const json kv =
      object("foxglove.KeyValuePair", {{"key", string_schema()}, {"value", string_schema()}});
  const json entity = object("foxglove.SceneEntity",
                             {{"timestamp", fj::time_schema()},
                              {"frame_id", string_schema()},
                              {"id", string_schema()},
                              {"lifetime", object("duration", {{"sec", {{"type", "integer"}}},
                                                               {"nsec", {{"type", "integer"}}}})},
                              {"frame_locked", {{"type", "boolean"}}},
                              {"metadata", array_of(kv)},
                              {"arrows", array_of({{"type", "object"}})},
                              {"cubes", array_of({{"type", "object"}})},
                              {"spheres", array_of({{"type", "object"}})},
                              {"cylinders", array_of({{"type", "object"}})},
                              {"lines", array_of(line)},
                              {"triangles", array_of(triangles)},
                              {"texts", array_of(text)},
                              {"models", array_of({{"type", "object"}})}});
  const json deletion =
      object("foxglove.SceneEntityDeletion",
             {{"timestamp", fj::time_schema()},
              {"type", {{"type", "integer"}, {"description", "0 = MATCHING_ID, 1 = ALL"}}},
              {"id", string_schema()}});
  return {"foxglove.SceneUpdate", object("foxglove.SceneUpdate", {{"deletions", array_of(deletion)},
                                                                  {"entities", array_of(entity)}})
                                      .dump()};
}

std::string pose_in_frame(TimeNs t_ns, const SE3d& T_world_body) {
  return json{{"timestamp", fj::time(t_ns)}, {"frame_id", "world"}, {"pose", pose(T_world_body)}}
      .dump();
}

std::string frame_transform(TimeNs t_ns, const SE3d& T_parent_child, const std::string& child,
                            const std::string& parent) {
  return json{
      {"timestamp", fj::time(t_ns)},
      {"parent_frame_id", parent},
      {"child_frame_id", child},
      {"translation", fj::vector3(T_parent_child.translation())},
      {"rotation", fj::quaternion(Eigen::Quaterniond(T_parent_child.linear()).normalized())}}
      .dump();
}

std::string point_cloud(TimeNs t_ns, const PointCloud& map, const std::vector<float>& sigma_m,
                        const std::vector<Wall>& walls) {
  constexpr std::size_t kStride = 7 * sizeof(float);  // x y z sigma r g b
  std::vector<std::uint8_t> data(map.size() * kStride);
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Eigen::Vector3d p(map.x[i], map.y[i], map.z[i]);
    std::array<float, 7> v{map.x[i], map.y[i], map.z[i], i < sigma_m.size() ? sigma_m[i] : 0.0f,
                           0.6f,     0.6f,     0.6f};
    for (const Wall& w : walls) {
      if (std::abs(w.plane.signed_distance(p)) > kOnSurfaceM) continue;
      const Eigen::Vector3d q = p - w.origin;
      if (!inside_convex(w.extent_uv_m, {q.dot(w.u), q.dot(w.v)})) continue;
      const auto c = surface_colour_rgb(w.id);
      v[4] = static_cast<float>(c[0]) / 255.0f;
      v[5] = static_cast<float>(c[1]) / 255.0f;
      v[6] = static_cast<float>(c[2]) / 255.0f;
      break;
    }
    std::memcpy(data.data() + i * kStride, v.data(), kStride);  // little-endian float32
  }
  json fields = json::array();
  const char* names[7] = {"x", "y", "z", "sigma", "red", "green", "blue"};
  for (int k = 0; k < 7; ++k) {
    fields.push_back({{"name", names[k]}, {"offset", 4 * k}, {"type", kFloat32}});
  }
  // base64: JSON Schema's contentEncoding, as Foxglove reads bytes.
  const std::string b64 = recording::base64_encode(data);
  return json{
      {"timestamp", fj::time(t_ns)}, {"frame_id", "world"}, {"pose", pose(SE3d::Identity())},
      {"point_stride", kStride},     {"fields", fields},    {"data", b64}}
      .dump();
}

std::string scene_update(TimeNs t_ns, const std::vector<Wall>& walls, bool replace_all) {
  json entities = json::array();
  const SE3d identity = SE3d::Identity();
  for (const Wall& w : walls) {
    const std::vector<Eigen::Vector3d> c = corners(w);
    json tri_points = json::array();
    for (std::size_t i = 1; i + 1 < c.size(); ++i) {  // the convex extent as a fan
      for (const std::size_t k : {std::size_t{0}, i, i + 1})
        tri_points.push_back(fj::vector3(c[k]));
    }
    json outline = json::array();
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : c) {
      outline.push_back(fj::vector3(p));
      centre += p;
    }
    if (!c.empty()) centre /= static_cast<double>(c.size());
    SE3d label = SE3d::Identity();
    label.translation() = centre + 0.05 * w.plane.n;  // just in front of the surface
    const std::string kind(to_string(w.kind));
    entities.push_back(
        {{"timestamp", fj::time(t_ns)},
         {"frame_id", "world"},
         {"id", "surface-" + std::to_string(w.id)},
         {"lifetime", {{"sec", 0}, {"nsec", 0}}},
         {"frame_locked", false},
         {"metadata",
          {{{"key", "kind"}, {"value", kind}},
           {{"key", "inliers"}, {"value", std::to_string(w.inliers)}},
           {{"key", "plane"},
            {"value", "n " + std::to_string(w.plane.n.x()) + " " + std::to_string(w.plane.n.y()) +
                          " " + std::to_string(w.plane.n.z()) + ", d " +
                          std::to_string(w.plane.d)}}}},
         {"arrows", json::array()},
         {"cubes", json::array()},
         {"spheres", json::array()},
         {"cylinders", json::array()},
         {"lines",
          {{{"type", 1},
            {"pose", pose(identity)},
            {"thickness", 2.0},
            {"scale_invariant", true},
            {"points", outline},
            {"color", colour(w.id, 1.0)},
            {"colors", json::array()},
            {"indices", json::array()}}}},
         {"triangles",
          {{{"pose", pose(identity)},
            {"points", tri_points},
            {"color", colour(w.id, 0.4)},
            {"colors", json::array()},
            {"indices", json::array()}}}},
         {"texts",
          {{{"pose", pose(label)},
            {"billboard", true},
            {"font_size", 14.0},
            {"scale_invariant", true},
            {"color", colour(w.id, 1.0)},
            {"text", kind + " " + std::to_string(w.id)}}}},
         {"models", json::array()}});
  }
  // Deletions come before the entities (Foxglove applies them first): ALL, then the new set.
  json deletions = json::array();
  if (replace_all) deletions.push_back({{"timestamp", fj::time(t_ns)}, {"type", 1}, {"id", ""}});
  return json{{"deletions", deletions}, {"entities", entities}}.dump();
}

Schema frame_transforms_schema() {
  const json one = object("foxglove.FrameTransform", {{"timestamp", fj::time_schema()},
                                                      {"parent_frame_id", string_schema()},
                                                      {"child_frame_id", string_schema()},
                                                      {"translation", vector3_schema()},
                                                      {"rotation", quaternion_schema()}});
  json s = object("foxglove.FrameTransforms", {{"transforms", array_of(one)}});
  s["required"] = {"transforms"};
  return {"foxglove.FrameTransforms", s.dump()};
}

Schema poses_in_frame_schema() {
  return {"foxglove.PosesInFrame",
          object("foxglove.PosesInFrame", {{"timestamp", fj::time_schema()},
                                           {"frame_id", string_schema()},
                                           {"poses", array_of(pose_schema())}})
              .dump()};
}

Schema compressed_image_schema() {
  return {"foxglove.CompressedImage", fj::compressed_image_schema().dump()};
}

Schema log_schema() {
  json s =
      object("foxglove.Log", {{"timestamp", fj::time_schema()},
                              {"level",
                               {{"type", "integer"},
                                {"description", "1 DEBUG, 2 INFO, 3 WARNING, 4 ERROR, 5 FATAL"},
                                {"minimum", 0},
                                {"maximum", 5}}},
                              {"message", string_schema()},
                              {"name", string_schema()},
                              {"file", string_schema()},
                              {"line", {{"type", "integer"}, {"minimum", 0}}}});
  s["required"] = {"timestamp", "level", "message", "name"};
  return {"foxglove.Log", s.dump()};
}

Schema stats_schema() {
  const json latency = object("wallar.Latency", {{"name", string_schema()},
                                                 {"count", {{"type", "integer"}}},
                                                 {"p50_ms", number()},
                                                 {"p99_ms", number()},
                                                 {"max_ms", number()},
                                                 {"mean_ms", number()},
                                                 {"deadline_ms", number()},
                                                 {"misses", {{"type", "integer"}}}});
  const json thread =
      object("wallar.Thread", {{"name", string_schema()},
                               {"policy", string_schema()},
                               {"cpu", {{"type", "integer"}}},
                               {"cpu_s", number()},
                               {"cpu_percent", number()},
                               {"wakeups", {{"type", "integer"}}},
                               {"misses", {{"type", "integer"}}},
                               {"allocations_after_start", {{"type", {"integer", "null"}}}},
                               {"note", string_schema()}});
  json s = object("wallar.Stats", {{"timestamp", fj::time_schema()},
                                   {"threads", array_of(thread)},
                                   {"stages", array_of(latency)},
                                   {"live", {{"type", "object"}}}});
  s["description"] = "The appliance's threads and stages (wallar run --stats), once a second";
  s["required"] = {"timestamp", "threads", "stages"};
  return {"wallar.Stats", s.dump()};
}

std::string frame_transforms(TimeNs t_ns, const std::vector<NamedTransform>& transforms) {
  json all = json::array();
  for (const NamedTransform& t : transforms) {
    all.push_back(
        {{"timestamp", fj::time(t_ns)},
         {"parent_frame_id", t.parent},
         {"child_frame_id", t.child},
         {"translation", fj::vector3(t.T_parent_child.translation())},
         {"rotation", fj::quaternion(Eigen::Quaterniond(t.T_parent_child.linear()).normalized())}});
  }
  return json{{"transforms", all}}.dump();
}

std::string poses_in_frame(TimeNs t_ns, std::span<const SE3d> T_world_body) {
  json poses = json::array();
  for (const SE3d& T : T_world_body) poses.push_back(pose(T));
  return json{{"timestamp", fj::time(t_ns)}, {"frame_id", "world"}, {"poses", poses}}.dump();
}

std::string compressed_image(TimeNs t_ns, const std::string& frame_id, const char* format,
                             std::span<const std::uint8_t> data) {
  return json{{"timestamp", fj::time(t_ns)},
              {"frame_id", frame_id},
              {"data", recording::base64_encode(data)},
              {"format", format}}
      .dump();
}

std::string log(TimeNs t_ns, LogLevel level, const std::string& message, const std::string& name) {
  return json{{"timestamp", fj::time(t_ns)},
              {"level", static_cast<int>(level)},
              {"message", message},
              {"name", name},
              {"file", ""},
              {"line", 0}}
      .dump();
}

std::string stats(TimeNs t_ns, const std::vector<ThreadRow>& threads,
                  const std::vector<StageRow>& stages,
                  const std::vector<std::pair<const char*, std::uint64_t>>& live) {
  json counters = json::object();
  for (const auto& [name, value] : live) counters[name] = value;
  return json{{"timestamp", fj::time(t_ns)},
              {"threads", to_json(threads)},
              {"stages", to_json(stages)},
              {"live", counters}}
      .dump();
}

}  // namespace wallar::firmware::foxglove
