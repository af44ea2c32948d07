// SPDX-License-Identifier: Apache-2.0
/// @file yaml.hpp
/// @brief A small YAML document tree over libyaml, every node with its file line, and typed
/// getters whose errors name the file, the line and the key path.
///
/// Reads the OpenCV flavour too ("%YAML:1.0" first line, !!opencv-matrix maps) and Kalibr's
/// nested lists. Aliases and anchors are refused (no billion laughs); nesting is capped.
///
/// Threading: a loaded YamlDocument is immutable; share it read-only.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace wallar::config {

class YamlNode {
 public:
  enum class Kind : std::uint8_t { kNull, kScalar, kSequence, kMap };

  [[nodiscard]] Kind kind() const { return kind_; }
  [[nodiscard]] bool is_map() const { return kind_ == Kind::kMap; }
  [[nodiscard]] bool is_sequence() const { return kind_ == Kind::kSequence; }
  [[nodiscard]] bool is_scalar() const { return kind_ == Kind::kScalar; }
  [[nodiscard]] int line() const { return line_; }
  /// Dotted key path from the root, e.g. "imu.data_ready.line" or "T_BS.data[3]".
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] const std::string& file() const { return *file_; }

  // Maps.
  [[nodiscard]] bool has(std::string_view key) const { return find(key) != nullptr; }
  [[nodiscard]] const YamlNode* find(std::string_view key) const;
  /// The child under `key`; throws "FILE:LINE: missing key 'PATH.key'" if absent.
  [[nodiscard]] const YamlNode& at(std::string_view key) const;
  [[nodiscard]] const std::vector<std::pair<std::string, YamlNode>>& entries() const {
    return map_;
  }
  /// Throws on the first key not in `allowed`, naming it and listing the allowed ones.
  void check_keys(std::initializer_list<std::string_view> allowed) const;

  // Sequences.
  [[nodiscard]] const std::vector<YamlNode>& items() const { return items_; }
  [[nodiscard]] std::size_t size() const { return is_map() ? map_.size() : items_.size(); }

  // Scalars, typed. Each throws "FILE:LINE: 'PATH' must be ..., got '...'" on mismatch.
  [[nodiscard]] const std::string& scalar() const;
  [[nodiscard]] std::string as_string() const { return scalar(); }
  [[nodiscard]] double as_double() const;
  [[nodiscard]] std::int64_t as_int() const;  //!< decimal or 0x hex
  [[nodiscard]] bool as_bool() const;
  /// A flat list of numbers of exactly `expected` entries (any size when expected == 0).
  [[nodiscard]] std::vector<double> as_doubles(std::size_t expected = 0) const;
  /// A matrix given as OpenCV {rows, cols, data}, a flat list, or a list of rows.
  [[nodiscard]] Eigen::MatrixXd as_matrix(int rows, int cols) const;

  // Convenience: typed child lookups, with a default when the key is absent.
  [[nodiscard]] double get_double(std::string_view key, double fallback) const;
  [[nodiscard]] std::int64_t get_int(std::string_view key, std::int64_t fallback) const;
  [[nodiscard]] std::string get_string(std::string_view key, std::string fallback) const;
  [[nodiscard]] bool get_bool(std::string_view key, bool fallback) const;

  /// Throws "FILE:LINE: 'PATH' <msg>".
  [[noreturn]] void fail(std::string_view msg) const;

 private:
  friend class YamlBuilder;
  Kind kind_ = Kind::kNull;
  int line_ = 0;
  std::string path_;
  const std::string* file_ = nullptr;
  std::string scalar_;
  bool quoted_ = false;
  std::vector<YamlNode> items_;
  std::vector<std::pair<std::string, YamlNode>> map_;
};

class YamlDocument {
 public:
  /// Reads and parses a file; throws InputError naming the file (and line) on any problem.
  static YamlDocument load_file(const std::filesystem::path& path);
  /// Parses text; `name` is used in error messages in place of a file name.
  static YamlDocument parse(std::string_view text, std::string name);

  YamlDocument(YamlDocument&&) noexcept;
  YamlDocument& operator=(YamlDocument&&) noexcept;
  ~YamlDocument();

  [[nodiscard]] const YamlNode& root() const { return *root_; }
  [[nodiscard]] const std::string& name() const { return *name_; }

 private:
  YamlDocument();
  // Heap-held so node back-pointers to the name stay valid when the document moves.
  std::unique_ptr<std::string> name_;
  std::unique_ptr<YamlNode> root_;
};

}  // namespace wallar::config
