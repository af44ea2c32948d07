// SPDX-License-Identifier: Apache-2.0
/// @file real.hpp
/// @brief `wallar eval real` (issue 4, item 5): the room found in a real EuRoC recording, and
/// the floor's orientation held against gravity from the IMU and from ground truth.
///
/// The map, by `map_source`:
///   appliance (default)  the map the appliance's modules build over the whole recording in lock
///                        step (the product's tracker and mapper; the caller runs it, see
///                        `appliance_map`), in the left camera of its first tracked frame;
///   orb                  a sparse map the study triangulates itself from rectified ORB matches
///                        of up to `pairs` stereo pairs spread over the recording (merged only
///                        when the IMU says the head was still; otherwise the first pair alone):
///                        a denser map from one viewpoint, independent of tracking, kept as the
///                        thesis's real-data figure.
/// The study pairs the frames as replay does, estimates gravity from the IMU over the frames'
/// span, finds walls, floor and ceiling gravity-aligned, and fits the floor's inliers freely in
/// 3-D to compare its normal with both gravities. It writes, each complete or absent:
///   real_overlay.png   the map's left image, surface points in their colours, floor outline
///   real_map.csv       x,y,z,surface (left camera frame [m]; floor, wall_N, ceiling or none)
///   real_summary.json  the returned summary (written last: its presence means all are there)
///
/// Threading: run_real_study runs in the calling thread and shares no state; concurrent calls
/// need their own OutputDir.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

#include "wallar/core/point_cloud.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/eval/output.hpp"

namespace wallar::eval {

/// A map made outside the study (the appliance's), in the raw left camera frame at `t_ns`.
struct GivenMap {
  PointCloud points;
  TimeNs t_ns = 0;          //!< the stereo pair whose left image the overlay is drawn on
  std::size_t frames = 0;   //!< stereo pairs that made it
  std::string description;  //!< e.g. "appliance, lock step"
};

enum class RealMapSource : std::uint8_t { kAppliance, kOrb };

struct RealStudyOptions {
  std::filesystem::path recording;  //!< EuRoC folder (ROOT or ROOT/mav0)
  RealMapSource map_source = RealMapSource::kAppliance;
  /// kAppliance: runs the appliance over the recording (firmware; the CLI provides it).
  std::function<GivenMap(const recording::EurocRecording&)> appliance_map;
  int pairs = 8;              //!< kOrb: stereo pairs for the sparse map, spread over the recording
  double threshold_m = 0.05;  //!< inlier band of the room search and of the point labels
  std::uint64_t seed = 1;     //!< room search's random seed
};

/// Runs the study into `out` and returns the summary. Throws InputError ("PATH: what") on bad
/// input: a missing or malformed recording, fewer stereo pairs than `pairs`, a bad option, or a
/// map too sparse to search. A recording without ground truth is fine: the summary says so and
/// the angles against ground truth are null.
nlohmann::json run_real_study(const RealStudyOptions& options, OutputDir& out);

}  // namespace wallar::eval
