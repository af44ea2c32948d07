// SPDX-License-Identifier: Apache-2.0
/// @file replay_plan.hpp
/// @brief The test tooling's replay plan: the recording `loops` times (0: until stopped), each
/// loop shifted past the previous one (LoopShift; loops follow each other one frame period
/// apart), with faults injected (FaultSink, times from the first loop's first sample). Plug it
/// into ApplianceOptions::replay_plan.
///
/// Threading: the plan is used by the replay module's thread (see ReplayPlan).
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "wallar/firmware/appliance/replay_module.hpp"
#include "wallar/firmware/hil/faults.hpp"

namespace wallar::firmware::hil {

/// The factory for ApplianceOptions::replay_plan.
std::function<std::unique_ptr<ReplayPlan>(const recording::EurocRecording&)> replay_plan(
    int loops, std::vector<FaultSpec> faults);

}  // namespace wallar::firmware::hil
