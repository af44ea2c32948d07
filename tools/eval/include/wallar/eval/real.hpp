// SPDX-License-Identifier: Apache-2.0
/// @file real.hpp
/// @brief `wallar eval real` (issue 4, item 5): the room found in a real EuRoC recording, and
/// the floor's orientation held against gravity from the IMU and from ground truth.
///
/// The study reads the recording itself (no replay thread): it pairs the left and right frames
/// as replay does, estimates gravity from the IMU over the frames' span, triangulates a sparse
/// map from up to `pairs` stereo pairs spread over the recording (merged only when the IMU says
/// the head was still; otherwise the first pair alone), finds walls, floor and ceiling
/// gravity-aligned, and fits the floor's inliers freely in 3-D to compare its normal with both
/// gravities. It writes, each complete or absent:
///   real_overlay.png   the first left image, surface points in their colours, floor outline
///   real_map.csv       x,y,z,surface (left camera frame [m]; floor, wall_N, ceiling or none)
///   real_summary.json  the returned summary (written last: its presence means all are there)
///
/// Threading: run_real_study runs in the calling thread and shares no state; concurrent calls
/// need their own OutputDir.
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "wallar/eval/output.hpp"

namespace wallar::eval {

struct RealStudyOptions {
  std::filesystem::path recording;  //!< EuRoC folder (ROOT or ROOT/mav0)
  int pairs = 8;                    //!< stereo pairs for the sparse map, spread over the recording
  double threshold_m = 0.05;        //!< inlier band of the room search and of the point labels
  std::uint64_t seed = 1;           //!< room search's random seed
};

/// Runs the study into `out` and returns the summary. Throws InputError ("PATH: what") on bad
/// input: a missing or malformed recording, fewer stereo pairs than `pairs`, a bad option, or a
/// map too sparse to search. A recording without ground truth is fine: the summary says so and
/// the angles against ground truth are null.
nlohmann::json run_real_study(const RealStudyOptions& options, OutputDir& out);

}  // namespace wallar::eval
