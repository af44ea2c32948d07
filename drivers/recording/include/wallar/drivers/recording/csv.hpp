// SPDX-License-Identifier: Apache-2.0
/// @file csv.hpp
/// @brief A strict CSV reader for sensor streams: every problem names the file and the line.
///
/// Lines starting with '#' (the EuRoC header) and blank lines are skipped; CR before LF is
/// accepted. Fields are split on ',' with surrounding spaces trimmed (no quoting: sensor CSVs
/// hold numbers and file names).
///
/// Threading: pure functions.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace wallar::recording {

struct CsvRow {
  const std::string* file = nullptr;  //!< for error messages
  int line = 0;                       //!< 1-based line number in the file
  std::vector<std::string_view> fields;

  [[nodiscard]] std::int64_t int64_at(std::size_t i, std::string_view what) const;
  [[nodiscard]] double double_at(std::size_t i, std::string_view what) const;
  [[noreturn]] void fail(std::string_view msg) const;
};

/// Calls on_row for every data row of `text`. Throws InputError "NAME:LINE: ..." for a row
/// with a number of fields other than `columns`.
void parse_csv(std::string_view text, const std::string& name, std::size_t columns,
               const std::function<void(const CsvRow&)>& on_row);

/// The whole file as text; throws InputError "PATH: ..." when missing or unreadable.
std::string read_text_file(const std::filesystem::path& path);

/// The shortest text that EuRoC-style writers produce for a double: 17 significant digits,
/// with ".0" appended to integral values ("0.0", "9.0"), so files round-trip byte-identical.
std::string format_euroc_double(double value);

}  // namespace wallar::recording
