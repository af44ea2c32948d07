// SPDX-License-Identifier: Apache-2.0
/// @file output.hpp
/// @brief Where evaluation results go: a folder whose files are only ever complete. Every file
/// is written as NAME.part and renamed into place when whole, so an interrupted or failed run
/// leaves no file that looks finished. Figures are drawn by gnuplot (Debian's gnuplot-nox) from
/// a script kept beside the PNG, so anyone can restyle and redraw them: `gnuplot NAME.gp`.
///
/// Threading: an OutputDir is used by one thread.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace wallar::eval {

/// True when a `gnuplot` executable is on PATH.
bool gnuplot_available();

/// A CSV table built in memory: a header line, then rows of numbers (shortest round-trip form)
/// and bare words.
class CsvTable {
 public:
  explicit CsvTable(std::vector<std::string> columns);
  CsvTable& add(double value);
  CsvTable& add(std::string_view word);  //!< must not contain ',' or a line break
  void end_row();                        //!< throws std::logic_error on a short or long row
  [[nodiscard]] const std::string& text() const { return text_; }
  [[nodiscard]] std::size_t rows() const { return rows_; }

 private:
  std::size_t columns_;
  std::size_t in_row_ = 0;
  std::size_t rows_ = 0;
  std::string text_;
};

/// Writes `content` to `path` through PATH.part and a rename, so an interrupted or failed run
/// never leaves a file that looks complete. Throws InputError naming the file on failure
/// (the .part is removed).
void write_file_atomically(const std::filesystem::path& path, std::string_view content);

class OutputDir {
 public:
  /// Creates `dir` and its parents; InputError naming it when that fails. With plots false,
  /// plot() only writes the script.
  explicit OutputDir(std::filesystem::path dir, bool plots = true);

  [[nodiscard]] const std::filesystem::path& path() const { return dir_; }
  [[nodiscard]] bool plots() const { return plots_; }

  /// Writes `content` to dir/name (via name.part and a rename); returns the final path.
  std::filesystem::path write(const std::string& name, std::string_view content);

  /// Writes `script` as dir/NAME.gp behind a preamble that sets a PNG terminal of width x height
  /// and `set output outfile` (outfile defaults to NAME.png), then runs gnuplot in dir (so data
  /// files are named relative to it) and renames its output into NAME.png. Returns the PNG's
  /// path, or nothing when plots are off. Throws std::runtime_error when gnuplot is missing or
  /// fails (its stderr is passed through).
  std::optional<std::filesystem::path> plot(const std::string& name, std::string_view script,
                                            int width_px = 900, int height_px = 650);

  /// Every file written so far, in order.
  [[nodiscard]] const std::vector<std::filesystem::path>& written() const { return written_; }

 private:
  std::filesystem::path dir_;
  bool plots_;
  std::vector<std::filesystem::path> written_;
};

}  // namespace wallar::eval
