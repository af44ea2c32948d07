// SPDX-License-Identifier: Apache-2.0
/// @file study_map.hpp
/// @brief The map `wallar eval real` (and `eval all`) studies by default: the appliance's, run
/// over the recording in lock step, in the left camera of its first tracked frame.
///
/// Threading: called from the command's thread; runs the appliance's threads itself.
#pragma once

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/eval/real.hpp"

namespace wallar::cli {

eval::GivenMap appliance_map_for_study(const recording::EurocRecording& rec);

}  // namespace wallar::cli
