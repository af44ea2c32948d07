// SPDX-License-Identifier: Apache-2.0
/// @file csv.cpp
/// @brief Strict CSV parsing with file:line errors.
#include "wallar/drivers/recording/csv.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include "wallar/core/error.hpp"

namespace wallar::recording {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) {
    s.remove_suffix(1);
  }
  return s;
}

}  // namespace

void CsvRow::fail(std::string_view msg) const { throw_input_error(*file, line, msg); }

std::int64_t CsvRow::int64_at(std::size_t i, std::string_view what) const {
  const std::string_view s = fields.at(i);
  std::int64_t value = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (s.empty() || ec != std::errc() || ptr != s.data() + s.size()) {
    fail(std::string(what) + " (column " + std::to_string(i + 1) + ") must be an integer, got '" +
         printable(s) + "'");
  }
  return value;
}

double CsvRow::double_at(std::size_t i, std::string_view what) const {
  const std::string_view s = fields.at(i);
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (s.empty() || ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(value)) {
    fail(std::string(what) + " (column " + std::to_string(i + 1) +
         ") must be a finite number, got '" + printable(s) + "'");
  }
  return value;
}

void parse_csv(std::string_view text, const std::string& name, std::size_t columns,
               const std::function<void(const CsvRow&)>& on_row) {
  CsvRow row;
  row.file = &name;
  row.fields.reserve(columns + 1);
  std::size_t pos = 0;
  int line = 0;
  while (pos < text.size()) {
    ++line;
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    const std::string_view raw = trim(text.substr(pos, eol - pos));
    pos = eol + 1;
    if (raw.empty() || raw.front() == '#') continue;
    if (raw.find('\0') != std::string_view::npos) {
      throw_input_error(name, line, "binary data (NUL byte) in a CSV file");
    }
    row.line = line;
    row.fields.clear();
    std::size_t start = 0;
    for (;;) {
      const std::size_t comma = raw.find(',', start);
      row.fields.push_back(trim(raw.substr(
          start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    if (row.fields.size() != columns) {
      throw_input_error(name, line,
                        "expected " + std::to_string(columns) + " fields, found " +
                            std::to_string(row.fields.size()) +
                            (row.fields.size() < columns ? " (short row)" : " (long row)"));
    }
    on_row(row);
  }
}

std::string read_text_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw_input_error(path.string(), 0, "no such file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path.string(), 0, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw_input_error(path.string(), 0, "read error");
  return text.str();
}

std::string format_euroc_double(double value) {
  char buf[40];
  const int n = std::snprintf(buf, sizeof buf, "%.17g", value);
  std::string out(buf, static_cast<std::size_t>(n));
  if (std::isfinite(value) && out.find_first_of(".eEn") == std::string::npos) out += ".0";
  return out;
}

}  // namespace wallar::recording
