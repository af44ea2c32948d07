// SPDX-License-Identifier: Apache-2.0
/// @file report.hpp
/// @brief Machine-readable (JSON) and human-readable reports of recordings and replays.
///
/// Threading: pure functions.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "wallar/drivers/recording/stream_stats.hpp"
#include "wallar/drivers/source/replay_source.hpp"

namespace wallar::firmware {

nlohmann::json to_json(const recording::StreamStats& s);
nlohmann::json to_json(const recording::RecordingStats& s);
nlohmann::json to_json(const source::ReplayStats& s, DurationNs tolerance_ns);

/// Multi-line text for people, one stream per line.
std::string to_text(const recording::RecordingStats& s);
std::string to_text(const source::ReplayStats& s, DurationNs tolerance_ns);

}  // namespace wallar::firmware
