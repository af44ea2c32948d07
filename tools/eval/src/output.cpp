// SPDX-License-Identifier: Apache-2.0
/// @file output.cpp
/// @brief Complete-or-absent result files and gnuplot figures.
#include "wallar/eval/output.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "wallar/core/error.hpp"

extern char** environ;

namespace wallar::eval {
namespace fs = std::filesystem;

bool gnuplot_available() {
  const char* path = std::getenv("PATH");
  if (path == nullptr) return false;
  std::string_view rest(path);
  while (!rest.empty()) {
    const std::size_t colon = rest.find(':');
    const std::string_view entry = rest.substr(0, colon);
    const fs::path candidate = fs::path(entry.empty() ? "." : std::string(entry)) / "gnuplot";
    if (::access(candidate.c_str(), X_OK) == 0) return true;
    if (colon == std::string_view::npos) break;
    rest.remove_prefix(colon + 1);
  }
  return false;
}

CsvTable::CsvTable(std::vector<std::string> columns) : columns_(columns.size()) {
  for (std::size_t i = 0; i < columns.size(); ++i) {
    if (i > 0) text_ += ',';
    text_ += columns[i];
  }
  text_ += '\n';
}

CsvTable& CsvTable::add(double value) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, value);
  return add(std::string_view(buf, static_cast<std::size_t>(res.ptr - buf)));
}

CsvTable& CsvTable::add(std::string_view word) {
  if (word.find_first_of(",\n\r") != std::string_view::npos) {
    throw std::logic_error("CsvTable: a field holds a separator: " + std::string(word));
  }
  if (in_row_ > 0) text_ += ',';
  text_ += word;
  ++in_row_;
  return *this;
}

void CsvTable::end_row() {
  if (in_row_ != columns_) {
    throw std::logic_error("CsvTable: row has " + std::to_string(in_row_) + " fields, header " +
                           std::to_string(columns_));
  }
  text_ += '\n';
  in_row_ = 0;
  ++rows_;
}

OutputDir::OutputDir(fs::path dir, bool plots) : dir_(std::move(dir)), plots_(plots) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec || !fs::is_directory(dir_)) {
    throw_input_error(dir_.string(), 0,
                      "cannot create output folder: " + (ec ? ec.message() : "not a folder"));
  }
}

void write_file_atomically(const fs::path& path, std::string_view content) {
  const fs::path tmp = path.string() + ".part";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) throw_input_error(tmp.string(), 0, "cannot open for writing");
  const bool ok = std::fwrite(content.data(), 1, content.size(), f) == content.size();
  if (std::fclose(f) != 0 || !ok) {
    std::remove(tmp.c_str());
    throw_input_error(tmp.string(), 0, "write failed (disk full?)");
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw_input_error(tmp.string(), 0, "cannot rename: " + ec.message());
  }
}

fs::path OutputDir::write(const std::string& name, std::string_view content) {
  fs::path final_path = dir_ / name;
  write_file_atomically(final_path, content);
  written_.push_back(final_path);
  return final_path;
}

std::optional<fs::path> OutputDir::plot(const std::string& name, std::string_view script,
                                        int width_px, int height_px) {
  std::string gp = "# " + name + ".png, drawn by `wallar eval`. Redraw from this folder with:\n" +
                   "#   gnuplot " + name + ".gp\n";
  gp += "if (!exists(\"outfile\")) outfile = \"" + name + ".png\"\n";
  gp += "set terminal pngcairo size " + std::to_string(width_px) + "," + std::to_string(height_px) +
        " font \"DejaVu Sans,11\" noenhanced\n";
  // NaN marks the rows a curve skips (`cond ? $3 : NaN`); as "missing" they do not break lines.
  gp += "set output outfile\nset datafile separator \",\"\nset datafile missing NaN\n";
  gp += script;
  write(name + ".gp", gp);
  if (!plots_) return std::nullopt;

  const std::string part = name + ".png.part";
  const std::string define = "outfile='" + part + "'";
  const std::string script_name = name + ".gp";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addchdir_np(&actions, dir_.c_str());
  // gnuplot's chatter goes to our stderr; stdin is not ours to give.
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  const char* argv[] = {"gnuplot", "-e", define.c_str(), script_name.c_str(), nullptr};
  pid_t pid = 0;
  const int err =
      posix_spawnp(&pid, "gnuplot", &actions, nullptr, const_cast<char* const*>(argv), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (err != 0) {
    throw std::runtime_error("cannot run gnuplot for " + (dir_ / name).string() +
                             ".png (tools/setup installs gnuplot-nox; --no-plots skips figures)");
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  const fs::path png_part = dir_ / part;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || !fs::exists(png_part)) {
    std::error_code ec;
    fs::remove(png_part, ec);
    throw std::runtime_error("gnuplot failed on " + (dir_ / script_name).string());
  }
  const fs::path png = dir_ / (name + ".png");
  std::error_code ec;
  fs::rename(png_part, png, ec);
  if (ec) throw_input_error(png_part.string(), 0, "cannot rename: " + ec.message());
  written_.push_back(png);
  return png;
}

}  // namespace wallar::eval
