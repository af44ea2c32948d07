// SPDX-License-Identifier: Apache-2.0
/// @file tum_trajectory.hpp
/// @brief Trajectories in the TUM RGB-D text format (what evo, rpg_trajectory_evaluation and
/// the TUM tools read): one pose a line, "t x y z qx qy qz qw", t in seconds.
///
/// Threading: pure functions.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/core/pose.hpp"

namespace wallar::recording {

/// One line per pose, "t x y z qx qy qz qw\n": t = t_ns in seconds with exactly 9 decimals
/// (lossless), the rest "%.9g"; the quaternion is the rotation of T_world_body with qw >= 0.
std::string format_tum(std::span<const StampedPose> poses);

/// Parses TUM text. '#' comment lines and blank lines are skipped; fields are separated by
/// spaces or tabs; CR before LF is accepted. t is read exactly to the nanosecond (decimal
/// seconds, at most 9 decimals used; more are rounded). The quaternion is normalised. Throws
/// InputError "SOURCE_NAME:LINE: ..." for a line without 8 numbers, a non-finite number, a
/// quaternion whose norm is not within 1 % of 1, or a time not after the previous line's.
std::vector<StampedPose> parse_tum(std::string_view text, std::string_view source_name);

}  // namespace wallar::recording
