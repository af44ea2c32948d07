// SPDX-License-Identifier: Apache-2.0
/// @file simd_targets.hpp
/// @brief Running a check on every SIMD target Highway compiled in and this CPU supports.
///
/// Threading: test-thread only (it forces the process-wide dispatch target).
#pragma once

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <string>

namespace wallar::test {

/// Forces the dispatcher to each SIMD target compiled in and supported by this CPU in turn (on
/// x86-64 e.g. AVX-512, AVX2, SSE4; Highway's scalar target cannot be forced there), runs
/// `check` under a trace naming it, then gives the dispatcher back the real CPU. With
/// WALLAR_SIMD_TARGETS=SVE only the targets whose name contains it run (the aarch64 CI stage's
/// second run, on qemu's 'max' CPU, checks the SVE kernels its Cortex-A76 run cannot reach).
/// Returns how many targets ran; the caller asserts it is at least one.
inline std::size_t for_each_simd_target(const std::function<void()>& check) {
  const char* only = std::getenv("WALLAR_SIMD_TARGETS");
  std::size_t ran = 0;
  for (std::int64_t target : hwy::SupportedAndGeneratedTargets()) {
    const std::string name = hwy::TargetName(target);
    if (only != nullptr && name.find(only) == std::string::npos) continue;
    hwy::SetSupportedTargetsForTest(target);
    SCOPED_TRACE("on " + name);
    check();
    ++ran;
  }
  hwy::SetSupportedTargetsForTest(0);  // back to the real CPU
  return ran;
}

/// What a test says when no target ran: the filter matched none.
inline std::string simd_filter() {
  const char* only = std::getenv("WALLAR_SIMD_TARGETS");
  return only != nullptr ? std::string("WALLAR_SIMD_TARGETS=") + only : std::string("no filter");
}

}  // namespace wallar::test
