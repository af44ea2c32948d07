// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_board.cpp
/// @brief Fuzzes the board file parser (schema checks, GPIO lines, path resolution).
#include <string>

#include "fuzz_common.hpp"
#include "wallar/firmware/board.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  wallar::fuzz::expect_only_input_errors([&] {
    const wallar::firmware::BoardConfig b = wallar::firmware::parse_board(
        wallar::fuzz::as_text(data, size), "board.yaml", "/etc/wallar/board");
    if (b.source == wallar::firmware::BoardConfig::Source::kReplay &&
        !b.replay.recording.is_absolute()) {
      __builtin_trap();  // relative paths resolve against the (absolute) base folder
    }
  });
  return 0;
}
