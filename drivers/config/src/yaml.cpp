// SPDX-License-Identifier: Apache-2.0
/// @file yaml.cpp
/// @brief YAML tree over libyaml's event parser, with line numbers and typed getters.
#include "wallar/drivers/config/yaml.hpp"

#include <yaml.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "wallar/core/error.hpp"

namespace wallar::config {
namespace {

constexpr int kMaxDepth = 32;                     // deeper nesting is no config of ours
constexpr std::size_t kMaxFileBytes = 16u << 20;  // 16 MiB

std::string child_path(const std::string& parent, std::string_view key) {
  if (parent.empty()) return std::string(key);
  return parent + "." + std::string(key);
}

}  // namespace

// Builds the tree from libyaml events. Lives in a class so it can reach YamlNode's privates.
class YamlBuilder {
 public:
  YamlBuilder(std::string_view text, const std::string* name) : name_(name) {
    yaml_parser_initialize(&parser_);
    yaml_parser_set_input_string(&parser_, reinterpret_cast<const unsigned char*>(text.data()),
                                 text.size());
  }
  ~YamlBuilder() { yaml_parser_delete(&parser_); }
  YamlBuilder(const YamlBuilder&) = delete;
  YamlBuilder& operator=(const YamlBuilder&) = delete;

  void build(YamlNode& root) {
    Event ev(*this);
    expect(ev, YAML_STREAM_START_EVENT);
    Event doc(*this);
    if (doc.e.type == YAML_STREAM_END_EVENT) {  // empty file
      throw_input_error(*name_, 0, "empty YAML document");
    }
    expect(doc, YAML_DOCUMENT_START_EVENT);
    Event first(*this);
    parse_node(first, root, "", 0);
    Event end(*this);
    expect(end, YAML_DOCUMENT_END_EVENT);
    Event next(*this);
    if (next.e.type != YAML_STREAM_END_EVENT) {
      throw_input_error(*name_, line_of(next.e), "more than one YAML document in the file");
    }
  }

 private:
  struct Event {
    explicit Event(YamlBuilder& b) {
      if (!yaml_parser_parse(&b.parser_, &e)) b.fail_parser();
    }
    ~Event() { yaml_event_delete(&e); }
    Event(const Event&) = delete;
    Event& operator=(const Event&) = delete;
    yaml_event_t e{};
  };

  static int line_of(const yaml_event_t& e) { return static_cast<int>(e.start_mark.line) + 1; }

  [[noreturn]] void fail_parser() {
    const int line = static_cast<int>(parser_.problem_mark.line) + 1;
    std::string msg = "YAML syntax error";
    if (parser_.problem != nullptr) msg += std::string(": ") + parser_.problem;
    if (parser_.context != nullptr) msg += std::string(" ") + parser_.context;
    throw_input_error(*name_, line, msg);
  }

  void expect(const Event& ev, yaml_event_type_t type) {
    if (ev.e.type != type) throw_input_error(*name_, line_of(ev.e), "unexpected YAML structure");
  }

  void parse_node(const Event& ev, YamlNode& node, std::string path, int depth) {
    node.file_ = name_;
    node.line_ = line_of(ev.e);
    node.path_ = std::move(path);
    if (depth > kMaxDepth) throw_input_error(*name_, node.line_, "YAML nested too deeply");
    switch (ev.e.type) {
      case YAML_ALIAS_EVENT:
        throw_input_error(*name_, node.line_, "YAML aliases are not supported");
      case YAML_SCALAR_EVENT: {
        const auto& s = ev.e.data.scalar;
        node.scalar_.assign(reinterpret_cast<const char*>(s.value), s.length);
        node.quoted_ = s.style == YAML_SINGLE_QUOTED_SCALAR_STYLE ||
                       s.style == YAML_DOUBLE_QUOTED_SCALAR_STYLE;
        const bool is_null = !node.quoted_ && (node.scalar_.empty() || node.scalar_ == "~" ||
                                               node.scalar_ == "null");
        node.kind_ = is_null ? YamlNode::Kind::kNull : YamlNode::Kind::kScalar;
        return;
      }
      case YAML_SEQUENCE_START_EVENT: {
        node.kind_ = YamlNode::Kind::kSequence;
        for (;;) {
          Event child(*this);
          if (child.e.type == YAML_SEQUENCE_END_EVENT) return;
          node.items_.emplace_back();
          parse_node(child, node.items_.back(),
                     node.path_ + "[" + std::to_string(node.items_.size() - 1) + "]", depth + 1);
        }
      }
      case YAML_MAPPING_START_EVENT: {
        node.kind_ = YamlNode::Kind::kMap;
        for (;;) {
          Event key(*this);
          if (key.e.type == YAML_MAPPING_END_EVENT) return;
          if (key.e.type != YAML_SCALAR_EVENT) {
            throw_input_error(*name_, line_of(key.e), "YAML map keys must be plain scalars");
          }
          std::string k(reinterpret_cast<const char*>(key.e.data.scalar.value),
                        key.e.data.scalar.length);
          for (const auto& [existing, unused] : node.map_) {
            if (existing == k) {
              throw_input_error(*name_, line_of(key.e),
                                "duplicate key '" + child_path(node.path_, k) + "'");
            }
          }
          Event value(*this);
          node.map_.emplace_back(k, YamlNode{});
          parse_node(value, node.map_.back().second, child_path(node.path_, k), depth + 1);
        }
      }
      default:
        throw_input_error(*name_, node.line_, "unexpected YAML event");
    }
  }

  yaml_parser_t parser_{};
  const std::string* name_;
};

// ---------------------------------------------------------------------------------------------
// YamlNode

void YamlNode::fail(std::string_view msg) const {
  throw_input_error(
      *file_, line_,
      "'" + (path_.empty() ? std::string("<root>") : path_) + "' " + std::string(msg));
}

const YamlNode* YamlNode::find(std::string_view key) const {
  if (!is_map()) return nullptr;
  for (const auto& [k, v] : map_) {
    if (k == key) return &v;
  }
  return nullptr;
}

const YamlNode& YamlNode::at(std::string_view key) const {
  if (!is_map()) fail("must be a map with the key '" + std::string(key) + "'");
  const YamlNode* child = find(key);
  if (child == nullptr) {
    throw_input_error(*file_, line_, "missing key '" + child_path(path_, key) + "'");
  }
  return *child;
}

void YamlNode::check_keys(std::initializer_list<std::string_view> allowed) const {
  if (!is_map()) fail("must be a map");
  for (const auto& [k, v] : map_) {
    bool ok = false;
    for (std::string_view a : allowed) ok = ok || a == k;
    if (!ok) {
      std::string list;
      for (std::string_view a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
      throw_input_error(*file_, v.line_,
                        "unknown key '" + child_path(path_, k) + "' (allowed: " + list + ")");
    }
  }
}

const std::string& YamlNode::scalar() const {
  if (kind_ != Kind::kScalar) fail("must be a scalar value");
  return scalar_;
}

double YamlNode::as_double() const {
  const std::string& s = scalar();
  double value = 0.0;
  const char* begin = s.data();
  const char* end = s.data() + s.size();
  if (begin != end && *begin == '+') ++begin;
  // from_chars takes a '-' of its own: without this check "+-1" would read as -1.
  const bool sign_after_plus = begin != s.data() && begin != end && *begin == '-';
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (sign_after_plus || ec != std::errc() || ptr != end || !std::isfinite(value)) {
    fail("must be a finite number, got '" + printable(s) + "'");
  }
  return value;
}

std::int64_t YamlNode::as_int() const {
  const std::string& s = scalar();
  std::int64_t value = 0;
  const char* begin = s.data();
  const char* end = s.data() + s.size();
  int base = 10;
  bool negative = false;
  if (begin != end && (*begin == '-' || *begin == '+')) {
    negative = *begin == '-';
    ++begin;
  }
  if (end - begin > 2 && begin[0] == '0' && (begin[1] == 'x' || begin[1] == 'X')) {
    base = 16;
    begin += 2;
  }
  // from_chars takes a '-' of its own: without this check "--5" and "-0x-5" would read as 5.
  const bool second_sign = begin != end && (*begin == '-' || *begin == '+');
  const auto [ptr, ec] = std::from_chars(begin, end, value, base);
  if (begin == end || second_sign || ec != std::errc() || ptr != end) {
    fail("must be an integer, got '" + printable(s) + "'");
  }
  return negative ? -value : value;
}

bool YamlNode::as_bool() const {
  const std::string& s = scalar();
  if (s == "true" || s == "True" || s == "yes" || s == "on") return true;
  if (s == "false" || s == "False" || s == "no" || s == "off") return false;
  fail("must be true or false, got '" + printable(s) + "'");
}

std::vector<double> YamlNode::as_doubles(std::size_t expected) const {
  if (!is_sequence()) fail("must be a list of numbers");
  if (expected != 0 && items_.size() != expected) {
    fail("must have " + std::to_string(expected) + " entries, has " +
         std::to_string(items_.size()));
  }
  std::vector<double> out;
  out.reserve(items_.size());
  for (const YamlNode& item : items_) out.push_back(item.as_double());
  return out;
}

Eigen::MatrixXd YamlNode::as_matrix(int rows, int cols) const {
  const std::string shape = std::to_string(rows) + "x" + std::to_string(cols);
  Eigen::MatrixXd m(rows, cols);
  if (is_map()) {  // OpenCV: {rows: R, cols: C, data: [...]}, maybe with dt.
    const std::int64_t r = at("rows").as_int();
    const std::int64_t c = at("cols").as_int();
    if (r != rows || c != cols) {
      fail("must be a " + shape + " matrix, is " + std::to_string(r) + "x" + std::to_string(c));
    }
    const std::vector<double> data = at("data").as_doubles(static_cast<std::size_t>(rows * cols));
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < cols; ++j) m(i, j) = data[static_cast<std::size_t>(i * cols + j)];
    }
    return m;
  }
  if (!is_sequence()) fail("must be a " + shape + " matrix");
  if (!items_.empty() && items_.front().is_sequence()) {  // Kalibr: list of rows
    if (items_.size() != static_cast<std::size_t>(rows)) {
      fail("must be a " + shape + " matrix, has " + std::to_string(items_.size()) + " rows");
    }
    for (int i = 0; i < rows; ++i) {
      const std::vector<double> row =
          items_[static_cast<std::size_t>(i)].as_doubles(static_cast<std::size_t>(cols));
      for (int j = 0; j < cols; ++j) m(i, j) = row[static_cast<std::size_t>(j)];
    }
    return m;
  }
  if (items_.size() != static_cast<std::size_t>(rows * cols)) {
    fail("must be a " + shape + " matrix, has " + std::to_string(items_.size()) + " entries");
  }
  const std::vector<double> data = as_doubles();
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) m(i, j) = data[static_cast<std::size_t>(i * cols + j)];
  }
  return m;
}

double YamlNode::get_double(std::string_view key, double fallback) const {
  const YamlNode* n = find(key);
  return n != nullptr ? n->as_double() : fallback;
}
std::int64_t YamlNode::get_int(std::string_view key, std::int64_t fallback) const {
  const YamlNode* n = find(key);
  return n != nullptr ? n->as_int() : fallback;
}
std::string YamlNode::get_string(std::string_view key, std::string fallback) const {
  const YamlNode* n = find(key);
  return n != nullptr ? n->as_string() : fallback;
}
bool YamlNode::get_bool(std::string_view key, bool fallback) const {
  const YamlNode* n = find(key);
  return n != nullptr ? n->as_bool() : fallback;
}

// ---------------------------------------------------------------------------------------------
// YamlDocument

YamlDocument::YamlDocument() = default;
YamlDocument::YamlDocument(YamlDocument&&) noexcept = default;
YamlDocument& YamlDocument::operator=(YamlDocument&&) noexcept = default;
YamlDocument::~YamlDocument() = default;

YamlDocument YamlDocument::parse(std::string_view text, std::string name) {
  YamlDocument doc;
  doc.name_ = std::make_unique<std::string>(std::move(name));
  doc.root_ = std::make_unique<YamlNode>();
  // OpenCV writes "%YAML:1.0", which is no YAML directive: blank it, keeping line numbers.
  std::string patched;
  if (text.starts_with("%YAML:")) {
    patched.assign(text);
    const std::size_t eol = patched.find('\n');
    patched.replace(0, eol == std::string::npos ? patched.size() : eol, "");
    text = patched;
  }
  YamlBuilder builder(text, doc.name_.get());
  builder.build(*doc.root_);
  return doc;
}

YamlDocument YamlDocument::load_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw_input_error(path.string(), 0, "no such file");
  }
  const auto size = std::filesystem::file_size(path, ec);
  if (ec || size > kMaxFileBytes) throw_input_error(path.string(), 0, "cannot read (too large?)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path.string(), 0, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return parse(text.str(), path.string());
}

}  // namespace wallar::config
