// SPDX-License-Identifier: Apache-2.0
/// @file report.hpp
/// @brief Machine-readable (JSON) and human-readable reports of recordings and replays.
///
/// Threading: pure functions.
#pragma once

#include <array>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "wallar/drivers/recording/rotating_writer.hpp"
#include "wallar/drivers/recording/stream_stats.hpp"
#include "wallar/drivers/source/async_recorder.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/walls/room.hpp"

namespace wallar::firmware {

nlohmann::json to_json(const recording::StreamStats& s);
nlohmann::json to_json(const recording::RecordingStats& s);
nlohmann::json to_json(const source::ReplayStats& s);
/// What a recorder did (drops, high water against capacity, write errors), as `wallar record`
/// and `wallar run --record` report it.
nlohmann::json to_json(const source::RecorderCounters& c, const source::AsyncRecorderOptions& o);
/// A rotating recording's segments: started, kept (names), deleted under the cap.
nlohmann::json to_json(const recording::RotatingWriter& r);

/// The `wallar walls` schema: {"surfaces":[{"id","kind","normal","d","inliers","backliers",
/// "score","rmse_m","extent"}], "rounds", "points"}.
nlohmann::json to_json(const dsp::RoomResult& r);
/// One line per surface.
std::string to_text(const dsp::RoomResult& r);
/// Reads that schema back (id, kind, normal, d and the extent's world corners; the rest is
/// optional) into a wall model; throws InputError "WHERE: surface K: ..." for what is missing
/// or implausible (non-unit normal, corners off the plane by > 5 cm, fewer than 3 corners).
WallModel walls_from_json(const nlohmann::json& j, const std::string& where);
/// The same from a file.
WallModel read_walls_json(const std::filesystem::path& path);
/// A colour per point: that of the first surface (in order of discovery) within threshold_m,
/// gray for points on none.
std::vector<std::array<std::uint8_t, 3>> surface_colours(const PointCloud& cloud,
                                                         const dsp::RoomResult& r,
                                                         double threshold_m);

/// Multi-line text for people, one stream per line.
std::string to_text(const recording::RecordingStats& s);
std::string to_text(const source::ReplayStats& s);

}  // namespace wallar::firmware
