// SPDX-License-Identifier: Apache-2.0
/// @file test_foxglove_messages.cpp
/// @brief The firmware's outputs as Foxglove messages: a pose's numbers, the map's packed
/// float32 points with their surface colours, a surface's extent as triangles and outline.
#include <gtest/gtest.h>

#include <cstring>
#include <nlohmann/json.hpp>

#include "wallar/firmware/foxglove_messages.hpp"

namespace wallar::test {
namespace {
namespace fg = firmware::foxglove;
using nlohmann::json;

std::vector<std::uint8_t> from_base64(const std::string& s) {
  std::vector<std::uint8_t> out;
  std::uint32_t v = 0;
  int bits = 0;
  for (const char c : s) {
    if (c == '=') break;
    const char* a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    v = (v << 6) | static_cast<std::uint32_t>(std::strchr(a, c) - a);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<std::uint8_t>(v >> bits));
    }
  }
  return out;
}

Wall square_wall() {  // x = 2, facing -x, 2 m wide and tall, centred on (2, 0, 1)
  Wall w;
  w.id = 5;
  w.kind = SurfaceKind::kWall;
  w.plane = Plane{Eigen::Vector3d(-1, 0, 0), -2.0};
  w.origin = Eigen::Vector3d(2, 0, 1);
  w.u = Eigen::Vector3d(0, 1, 0);
  w.v = Eigen::Vector3d(0, 0, 1);
  w.extent_uv_m = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  return w;
}

TEST(FoxgloveMessages, PoseAndTransformCarryTheTimeAndThePose) {
  SE3d T = SE3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(1, 2, 3);
  const json p = json::parse(fg::pose_in_frame(1'500'000'001, T));
  EXPECT_EQ(p["timestamp"]["sec"], 1);
  EXPECT_EQ(p["timestamp"]["nsec"], 500'000'001);
  EXPECT_EQ(p["frame_id"], "world");
  EXPECT_EQ(p["pose"]["position"]["y"], 2.0);
  EXPECT_NEAR(p["pose"]["orientation"]["z"].get<double>(), std::sin(0.25), 1e-15);
  const json t = json::parse(fg::frame_transform(7, T, "body"));
  EXPECT_EQ(t["child_frame_id"], "body");
  EXPECT_NEAR(t["rotation"]["w"].get<double>(), std::cos(0.25), 1e-15);
  EXPECT_EQ(json::parse(fg::pose_in_frame_schema().json_schema)["title"], "foxglove.PoseInFrame");
}

TEST(FoxgloveMessages, TheMapIsPackedFloat32WithSurfaceColours) {
  PointCloud map;
  map.x = {2.05f, 0.0f, 2.0f};  // on the wall; in the room; on the plane but outside its extent
  map.y = {0.5f, 0.0f, 3.0f};
  map.z = {1.0f, 1.0f, 1.0f};
  const json c = json::parse(fg::point_cloud(9, map, {0.01f, 0.02f, 0.03f}, {square_wall()}));
  ASSERT_EQ(c["point_stride"], 28);
  ASSERT_EQ(c["fields"].size(), 7u);
  EXPECT_EQ(c["fields"][3]["name"], "sigma");
  EXPECT_EQ(c["fields"][3]["offset"], 12);
  const std::vector<std::uint8_t> data = from_base64(c["data"]);
  ASSERT_EQ(data.size(), 3u * 28u);
  std::array<float, 21> f{};
  std::memcpy(f.data(), data.data(), data.size());
  EXPECT_EQ(f[0], 2.05f);
  EXPECT_EQ(f[3], 0.01f);
  const auto rgb = surface_colour_rgb(5);
  EXPECT_EQ(f[4], rgb[0] / 255.0f);  // the wall's colour
  EXPECT_EQ(f[6], rgb[2] / 255.0f);
  EXPECT_EQ(f[7 + 4], 0.6f);   // grey: off every surface
  EXPECT_EQ(f[14 + 4], 0.6f);  // grey: on the plane, outside the extent
  EXPECT_EQ(f[14 + 3], 0.03f);
}

TEST(FoxgloveMessages, ASurfaceIsItsExtentInTrianglesWithOutlineAndLabel) {
  const json s = json::parse(fg::scene_update(3 * kNsPerS, {square_wall()}));
  ASSERT_EQ(s["entities"].size(), 1u);
  const json& e = s["entities"][0];
  EXPECT_EQ(e["id"], "surface-5");
  EXPECT_EQ(e["timestamp"]["sec"], 3);
  ASSERT_EQ(e["triangles"][0]["points"].size(), 6u);  // a square: two triangles
  double area = 0.0;
  const json& p = e["triangles"][0]["points"];
  for (int t = 0; t < 2; ++t) {
    Eigen::Vector3d v[3];
    for (int k = 0; k < 3; ++k) {
      const json& q = p[3 * t + k];
      v[k] = Eigen::Vector3d(q["x"], q["y"], q["z"]);
      EXPECT_EQ(v[k].x(), 2.0);  // on the plane
    }
    area += 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).norm();
  }
  EXPECT_NEAR(area, 4.0, 1e-12);
  EXPECT_EQ(e["lines"][0]["points"].size(), 4u);
  EXPECT_EQ(e["lines"][0]["type"], 1);  // LINE_LOOP
  EXPECT_EQ(e["texts"][0]["text"], "wall 5");
  EXPECT_LT(e["texts"][0]["pose"]["position"]["x"].get<double>(), 2.0);  // in front of it
  EXPECT_EQ(json::parse(fg::scene_update_schema().json_schema)["title"], "foxglove.SceneUpdate");
  EXPECT_TRUE(s["deletions"].empty());  // a file's one update adds
  // A live update replaces the scene: a deletion of ALL before its entities.
  const json live = json::parse(fg::scene_update(3 * kNsPerS, {square_wall()}, true));
  ASSERT_EQ(live["deletions"].size(), 1u);
  EXPECT_EQ(live["deletions"][0]["type"], 1);
  EXPECT_EQ(live["entities"].size(), 1u);
}

TEST(FoxgloveMessages, TransformsPathImageLogAndStatsCarryTheirFields) {
  SE3d T = SE3d::Identity();
  T.translation() = Eigen::Vector3d(1, 2, 3);
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const json tf = json::parse(fg::frame_transforms(
      5 * kNsPerS + 7, {{"world", "body", T}, {"body", "cam0", SE3d::Identity()}}));
  ASSERT_EQ(tf["transforms"].size(), 2u);
  EXPECT_EQ(tf["transforms"][0]["parent_frame_id"], "world");
  EXPECT_EQ(tf["transforms"][0]["child_frame_id"], "body");
  EXPECT_EQ(tf["transforms"][0]["translation"]["z"], 3.0);
  EXPECT_NEAR(tf["transforms"][0]["rotation"]["z"].get<double>(), std::sqrt(0.5), 1e-12);
  EXPECT_EQ(tf["transforms"][1]["timestamp"]["nsec"], 7);

  const std::vector<SE3d> path{SE3d::Identity(), T};
  const json p = json::parse(fg::poses_in_frame(1, path));
  ASSERT_EQ(p["poses"].size(), 2u);
  EXPECT_EQ(p["poses"][1]["position"]["y"], 2.0);
  EXPECT_EQ(p["frame_id"], "world");

  const std::vector<std::uint8_t> bytes{0xff, 0xd8, 0xff, 0xe0, 0x01};
  const json img = json::parse(fg::compressed_image(2, "cam1", "jpeg", bytes));
  EXPECT_EQ(img["format"], "jpeg");
  EXPECT_EQ(img["frame_id"], "cam1");
  EXPECT_EQ(from_base64(img["data"].get<std::string>()), bytes);

  const json log = json::parse(fg::log(3, fg::LogLevel::kWarning, "camera lost", "wallar"));
  EXPECT_EQ(log["level"], 3);
  EXPECT_EQ(log["message"], "camera lost");
  EXPECT_EQ(log["name"], "wallar");

  firmware::ThreadRow thread;
  thread.name = "tracking";
  thread.policy = "FIFO 60";
  thread.allocations = 0;
  firmware::StageRow stage;
  stage.name = "tracking";
  stage.latency.p50_ms = 4.5;
  stage.deadline_ns = 50 * kNsPerMs;
  const json st = json::parse(fg::stats(4, {thread}, {stage}, {{"sent", 12}, {"dropped", 3}}));
  EXPECT_EQ(st["threads"][0]["policy"], "FIFO 60");
  EXPECT_EQ(st["threads"][0]["allocations_after_start"], 0);
  EXPECT_EQ(st["stages"][0]["p50_ms"], 4.5);
  EXPECT_EQ(st["stages"][0]["deadline_ms"], 50.0);
  EXPECT_EQ(st["live"]["dropped"], 3);
  // Each schema names its Foxglove type and what its messages must hold.
  for (const fg::Schema& schema :
       {fg::frame_transforms_schema(), fg::poses_in_frame_schema(), fg::compressed_image_schema(),
        fg::log_schema(), fg::stats_schema()}) {
    const json j = json::parse(schema.json_schema);
    EXPECT_EQ(j["title"], schema.name);
    EXPECT_EQ(j["type"], "object");
  }
  EXPECT_EQ(json::parse(fg::log_schema().json_schema)["required"].size(), 4u);
}

}  // namespace
}  // namespace wallar::test
