// SPDX-License-Identifier: Apache-2.0
/// @file error.hpp
/// @brief The error every reader throws for bad input: one line naming what and where.
///
/// Readers throw InputError with a message "FILE:LINE: what is wrong" (or "FILE: ..." when no
/// line applies). The CLI prints it on one stderr line and exits with kExitBadInput; nothing
/// else in the project may crash on bad input.
///
/// Threading: value type.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace wallar {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A device that cannot be opened or stopped answering (I2C adapter, GPIO chip, serial port,
/// USB device): "DEVICE: what failed: strerror". Not the user's input, so the CLI exits with
/// kExitFailure, not kExitBadInput.
class DeviceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A bad value quoted in an error message: at most max_chars, non-printable bytes as '?',
/// so a binary or hostile input cannot garble the one-line error.
inline std::string printable(std::string_view s, std::size_t max_chars = 40) {
  std::string out;
  for (char c : s.substr(0, max_chars)) out += (c >= 32 && c < 127) ? c : '?';
  if (s.size() > max_chars) out += "...";
  return out;
}

/// "path:line: message" (line 0 means the whole file: "path: message").
[[noreturn]] inline void throw_input_error(std::string_view path, int line, std::string_view msg) {
  std::string text(path);
  if (line > 0) text += ":" + std::to_string(line);
  text += ": ";
  text += msg;
  throw InputError(text);
}

}  // namespace wallar
