// SPDX-License-Identifier: Apache-2.0
/// @file report.cpp
/// @brief Stats reports.
#include "wallar/firmware/report.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>

#include "wallar/core/error.hpp"
#include "wallar/dsp/walls/room_check.hpp"

namespace wallar::firmware {

nlohmann::json to_json(const recording::StreamStats& s) {
  return {{"name", s.name},
          {"count", s.count},
          {"first_t_ns", s.first_t_ns},
          {"last_t_ns", s.last_t_ns},
          {"duration_s", s.duration_s()},
          {"nominal_rate_hz", s.nominal_rate_hz},
          {"mean_rate_hz", s.mean_rate_hz},
          {"median_period_ms", static_cast<double>(s.median_period_ns) * 1e-6},
          {"max_period_ms", static_cast<double>(s.max_period_ns) * 1e-6},
          {"max_gap_at_ns", s.max_gap_at_ns},
          {"gaps", s.gaps},
          {"missing_samples", s.missing_samples}};
}

nlohmann::json to_json(const recording::RecordingStats& s) {
  return {{"cam0", to_json(s.cams[0])},
          {"cam1", to_json(s.cams[1])},
          {"imu0", to_json(s.imu)},
          {"ground_truth_rows", s.ground_truth_rows}};
}

nlohmann::json to_json(const source::ReplayStats& s) {
  return {{"imu_samples", s.imu_samples},
          {"frames", {s.frames[0], s.frames[1]}},
          {"pairs_delivered", s.pairs_delivered},
          {"pairs_skipped", s.pairs_skipped},
          {"pairing",
           {{"pairs", s.pairing.pairs},
            {"unpaired", {s.pairing.unpaired[0], s.pairing.unpaired[1]}},
            {"tolerance_ms", static_cast<double>(s.pair_tolerance_ns) * 1e-6},
            {"mean_abs_skew_ms", s.pairing.mean_abs_skew_ns() * 1e-6},
            {"max_abs_skew_ms", static_cast<double>(s.pairing.max_abs_skew_ns) * 1e-6}}},
          {"first_t_ns", s.first_t_ns},
          {"last_t_ns", s.last_t_ns},
          {"wall_time_s", ns_to_s(s.wall_time_ns)},
          {"max_lateness_ms", static_cast<double>(s.max_lateness_ns) * 1e-6},
          {"stopped", s.stopped}};
}

nlohmann::json to_json(const recording::RotatingWriter& r) {
  const recording::RotationCounters& c = r.counters();
  nlohmann::json kept = nlohmann::json::array();
  for (const std::filesystem::path& p : r.segments()) kept.push_back(p.filename().string());
  return {{"segments_started", c.segments_started},
          {"segments_kept", kept.size()},
          {"segments_deleted", c.segments_deleted},
          {"bytes_deleted", c.bytes_deleted},
          {"delete_errors", c.delete_errors},
          {"first_kept", kept.front()},
          {"kept", kept}};
}

nlohmann::json to_json(const source::RecorderCounters& c, const source::AsyncRecorderOptions& o) {
  return {{"imu_dropped", c.imu_dropped},           {"frames_dropped", c.frames_dropped},
          {"imu_high_water", c.imu_high_water},     {"imu_capacity", o.imu_capacity},
          {"frame_high_water", c.frame_high_water}, {"frame_capacity", o.frame_capacity},
          {"pairs_written", c.pairs_written},       {"frames_not_copied", c.frames_not_copied},
          {"write_errors", c.write_errors},         {"error", c.error}};
}

namespace {
std::string line(const recording::StreamStats& s) {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "%-5s %6llu samples over %7.3f s: %8.3f Hz (nominal %g), median period %.3f ms, "
                "max %.3f ms; %llu gaps, %llu missing\n",
                s.name.c_str(), static_cast<unsigned long long>(s.count), s.duration_s(),
                s.mean_rate_hz, s.nominal_rate_hz, static_cast<double>(s.median_period_ns) * 1e-6,
                static_cast<double>(s.max_period_ns) * 1e-6,
                static_cast<unsigned long long>(s.gaps),
                static_cast<unsigned long long>(s.missing_samples));
  return buf;
}
}  // namespace

std::string to_text(const recording::RecordingStats& s) {
  std::string out = line(s.cams[0]) + line(s.cams[1]) + line(s.imu);
  out += "ground truth rows: " + std::to_string(s.ground_truth_rows) + "\n";
  return out;
}

std::string to_text(const source::ReplayStats& s) {
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "replayed %llu IMU samples, %llu + %llu frames in %.3f s (max lateness %.3f ms)\n"
      "stereo pairing (tolerance %.3f ms): %llu pairs, unpaired left %llu, right %llu, "
      "skew mean %.3f ms max %.3f ms; delivered %llu, skipped %llu%s\n",
      static_cast<unsigned long long>(s.imu_samples), static_cast<unsigned long long>(s.frames[0]),
      static_cast<unsigned long long>(s.frames[1]), ns_to_s(s.wall_time_ns),
      static_cast<double>(s.max_lateness_ns) * 1e-6,
      static_cast<double>(s.pair_tolerance_ns) * 1e-6,
      static_cast<unsigned long long>(s.pairing.pairs),
      static_cast<unsigned long long>(s.pairing.unpaired[0]),
      static_cast<unsigned long long>(s.pairing.unpaired[1]), s.pairing.mean_abs_skew_ns() * 1e-6,
      static_cast<double>(s.pairing.max_abs_skew_ns) * 1e-6,
      static_cast<unsigned long long>(s.pairs_delivered),
      static_cast<unsigned long long>(s.pairs_skipped), s.stopped ? " (stopped early)" : "");
  return buf;
}

nlohmann::json to_json(const dsp::RoomResult& r) {
  nlohmann::json surfaces = nlohmann::json::array();
  for (const auto& s : r.surfaces) {
    const Wall& w = s.wall;
    nlohmann::json extent = nlohmann::json::array();
    for (std::size_t i = 0; i < w.extent_uv_m.size(); ++i) {
      const Eigen::Vector3d c = w.corner(i);
      extent.push_back({c.x(), c.y(), c.z()});
    }
    surfaces.push_back({{"id", w.id},
                        {"kind", std::string(to_string(w.kind))},
                        {"normal", {w.plane.n.x(), w.plane.n.y(), w.plane.n.z()}},
                        {"d", w.plane.d},
                        {"inliers", w.inliers},
                        {"backliers", w.backliers},
                        {"score", s.score},
                        {"rmse_m", s.rmse_m},
                        {"extent", extent}});
  }
  nlohmann::json searches = nlohmann::json::array();
  for (const dsp::RoomSearch& s : r.searches) {
    nlohmann::json j = {{"outcome", dsp::to_string(s.outcome)},
                        {"inliers", s.inliers},
                        {"rounds", s.rounds},
                        {"ms", 1e3 * ns_to_s(s.time_ns)}};
    if (s.excess_sigma != 0.0) j["excess_sigma"] = s.excess_sigma;
    if (s.found_surface()) {
      j["kind"] = std::string(to_string(s.kind));
    }
    if (s.horizontal_rounds > 0) {
      j["horizontal_rounds"] = s.horizontal_rounds;
      j["horizontal_ms"] = 1e3 * ns_to_s(s.horizontal_time_ns);
    }
    searches.push_back(std::move(j));
  }
  return {{"surfaces", surfaces},
          {"rounds", r.rounds},
          {"points", r.points},
          {"stages",
           {{"setup_ms", 1e3 * ns_to_s(r.setup_ns)},
            {"searches", searches},
            {"finish_ms", 1e3 * ns_to_s(r.finish_ns)}}}};
}

WallModel walls_from_json(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object() || !j.contains("surfaces") || !j["surfaces"].is_array()) {
    throw_input_error(where, 0, "no \"surfaces\" array (expected the output of wallar walls)");
  }
  WallModel model;
  // wallar's files say how the search ran ("2-D (...)": with down, so the kinds hold).
  model.gravity_aligned = j.contains("mode") && j["mode"].is_string() &&
                          j["mode"].get<std::string>().rfind("2-D", 0) == 0;
  std::size_t k = 0;
  for (const nlohmann::json& s : j["surfaces"]) {
    const std::string at = "surface " + std::to_string(k++);
    const auto fail = [&](const std::string& what) {
      throw_input_error(where, 0, at + ": " + what);
    };
    const auto vec3 = [&](const nlohmann::json& v, const char* name) {
      if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
          !v[2].is_number()) {
        fail(std::string(name) + " is not [x, y, z]");
      }
      const Eigen::Vector3d out(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
      if (!out.allFinite()) fail(std::string(name) + " is not finite");
      return out;
    };
    if (!s.is_object()) fail("not an object");
    Wall w;
    if (!s.contains("id") || !s["id"].is_number_unsigned()) fail("no unsigned \"id\"");
    w.id = s["id"].get<std::uint32_t>();
    const std::string kind = s.value("kind", "wall");
    if (kind == "floor") {
      w.kind = SurfaceKind::kFloor;
    } else if (kind == "ceiling") {
      w.kind = SurfaceKind::kCeiling;
    } else if (kind != "wall") {
      fail("unknown kind '" + kind + "' (wall, floor, ceiling)");
    }
    if (!s.contains("normal") || !s.contains("d") || !s["d"].is_number()) fail("no normal and d");
    w.plane.n = vec3(s["normal"], "normal");
    w.plane.d = s["d"].get<double>();
    if (std::abs(w.plane.n.norm() - 1.0) > 1e-3) fail("normal is not a unit vector");
    if (!s.contains("extent") || !s["extent"].is_array() || s["extent"].size() < 3) {
      fail("extent needs at least 3 corners");
    }
    std::vector<Eigen::Vector3d> corners;
    for (const nlohmann::json& c : s["extent"]) corners.push_back(vec3(c, "extent corner"));
    for (const Eigen::Vector3d& c : corners) {
      if (std::abs(w.plane.signed_distance(c)) > 0.05)
        fail("extent corner off the plane by > 5 cm");
    }
    // Basis in the plane: u along the first edge, v = n x u (u x v = n).
    w.origin = corners[0];
    Eigen::Vector3d u = corners[1] - corners[0];
    u -= u.dot(w.plane.n) * w.plane.n;
    if (u.norm() < 1e-6) fail("the first two extent corners coincide");
    w.u = u.normalized();
    w.v = w.plane.n.cross(w.u);
    for (const Eigen::Vector3d& c : corners) {
      w.extent_uv_m.emplace_back((c - w.origin).dot(w.u), (c - w.origin).dot(w.v));
    }
    w.inliers = s.value("inliers", 0u);
    w.backliers = s.value("backliers", 0u);
    model.walls.push_back(std::move(w));
  }
  return model;
}

WallModel read_walls_json(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw_input_error(path.string(), 0, "cannot open the walls file");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw_input_error(path.string(), 0, std::string("not JSON: ") + e.what());
  }
  return walls_from_json(j, path.string());
}

std::string to_text(const dsp::RoomResult& r) {
  std::string out;
  for (const auto& s : r.surfaces) {
    const Wall& w = s.wall;
    char line[256];
    std::snprintf(line, sizeof line,
                  "  %-7s id %u: n = (%+.4f, %+.4f, %+.4f), d = %+.4f m, %u inliers, %u "
                  "backliers, rmse %.4f m\n",
                  std::string(to_string(w.kind)).c_str(), w.id, w.plane.n.x(), w.plane.n.y(),
                  w.plane.n.z(), w.plane.d, w.inliers, w.backliers, s.rmse_m);
    out += line;
  }
  return out;
}

std::vector<std::array<std::uint8_t, 3>> surface_colours(const PointCloud& cloud,
                                                         const dsp::RoomResult& r,
                                                         double threshold_m) {
  const std::vector<int> surface = dsp::surface_of_points(cloud, r, threshold_m);
  std::vector<std::array<std::uint8_t, 3>> rgb(cloud.size(), dsp::kNoSurfaceRgb);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (surface[i] >= 0) {
      rgb[i] = dsp::surface_colour_rgb(r.surfaces[static_cast<std::size_t>(surface[i])].wall.id);
    }
  }
  return rgb;
}

}  // namespace wallar::firmware
