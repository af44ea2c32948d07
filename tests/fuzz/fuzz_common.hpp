// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_common.hpp
/// @brief Shared glue for the libFuzzer targets: bad input must end in wallar::InputError;
/// anything else (another exception, a sanitizer report, a crash) is a finding.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "wallar/core/error.hpp"

namespace wallar::fuzz {

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// Runs `body`; swallows InputError (the documented answer to bad input) and nothing else, so
/// any other exception escapes LLVMFuzzerTestOneInput and libFuzzer reports it as a crash.
template <typename Body>
void expect_only_input_errors(Body&& body) {
  try {
    body();
  } catch (const InputError&) {
  }
}

}  // namespace wallar::fuzz
