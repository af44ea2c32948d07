// SPDX-License-Identifier: Apache-2.0
/// @file cloud_io.cpp
/// @brief Hand-written PLY / PCD / CSV point-cloud readers and a binary PLY writer.
///
/// Every read of the input goes through a bounds check against the bytes actually present, and
/// every size computed from header numbers is overflow-checked before use, so that hostile
/// input can only end in InputError (tests/fuzz/fuzz_cloud.cpp).
#include "wallar/drivers/cloud/cloud_io.hpp"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/csv.hpp"

namespace wallar::cloud {
namespace {

// ---------------------------------------------------------------------------------------------
// Small text helpers

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

void split_ws(std::string_view s, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_blank(s[i])) ++i;
    const std::size_t start = i;
    while (i < s.size() && !is_blank(s[i])) ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
}

void split_comma(std::string_view s, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = s.find(',', start);
    out.push_back(trim(
        s.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
}

/// A decimal number ("1", "-2.5e3", "nan", "inf"; a leading '+' is allowed), nothing else.
bool parse_double(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty() || s.front() == '+') return false;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && ptr == s.data() + s.size();
}

bool parse_u64(std::string_view s, std::uint64_t& out) {
  if (s.empty()) return false;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && ptr == s.data() + s.size();
}

/// Lines of a text (LF or CRLF), numbered from `first_line`; pos() is the offset just after
/// the last line returned (where binary data following a header starts).
class Lines {
 public:
  explicit Lines(std::string_view text, int first_line = 1) : text_(text), line_(first_line - 1) {}
  bool next(std::string_view& out) {
    if (pos_ >= text_.size()) return false;
    std::size_t eol = text_.find('\n', pos_);
    if (eol == std::string_view::npos) eol = text_.size();
    out = text_.substr(pos_, eol - pos_);
    if (!out.empty() && out.back() == '\r') out.remove_suffix(1);
    pos_ = std::min(eol + 1, text_.size());
    ++line_;
    return true;
  }
  /// Next line that is not blank (after trimming), trimmed.
  bool next_nonblank(std::string_view& out) {
    while (next(out)) {
      out = trim(out);
      if (!out.empty()) return true;
    }
    return false;
  }
  [[nodiscard]] int line() const { return line_; }
  [[nodiscard]] std::size_t pos() const { return pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  int line_;
};

// ---------------------------------------------------------------------------------------------
// Checked size arithmetic

std::optional<std::uint64_t> checked_mul(std::uint64_t a, std::uint64_t b) {
  std::uint64_t r = 0;
  if (__builtin_mul_overflow(a, b, &r)) return std::nullopt;
  return r;
}

std::optional<std::uint64_t> checked_add(std::uint64_t a, std::uint64_t b) {
  std::uint64_t r = 0;
  if (__builtin_add_overflow(a, b, &r)) return std::nullopt;
  return r;
}

// ---------------------------------------------------------------------------------------------
// Binary scalars

enum class Scalar : std::uint8_t { kI8, kU8, kI16, kU16, kI32, kU32, kI64, kU64, kF32, kF64 };

std::size_t scalar_size(Scalar t) {
  switch (t) {
    case Scalar::kI8:
    case Scalar::kU8:
      return 1;
    case Scalar::kI16:
    case Scalar::kU16:
      return 2;
    case Scalar::kI32:
    case Scalar::kU32:
    case Scalar::kF32:
      return 4;
    case Scalar::kI64:
    case Scalar::kU64:
    case Scalar::kF64:
      return 8;
  }
  return 1;
}

bool is_integer(Scalar t) { return t != Scalar::kF32 && t != Scalar::kF64; }

template <typename U>
U load_bits(const char* p, bool swap) {
  U v;
  std::memcpy(&v, p, sizeof v);
  if (swap) {
    if constexpr (sizeof(U) == 2) v = __builtin_bswap16(v);
    if constexpr (sizeof(U) == 4) v = __builtin_bswap32(v);
    if constexpr (sizeof(U) == 8) v = __builtin_bswap64(v);
  }
  return v;
}

/// The scalar of type `t` at p (which must have scalar_size(t) readable bytes).
double load_scalar(const char* p, Scalar t, bool big_endian_data) {
  const bool swap = big_endian_data != (std::endian::native == std::endian::big);
  switch (t) {
    case Scalar::kI8:
      return static_cast<std::int8_t>(static_cast<unsigned char>(*p));
    case Scalar::kU8:
      return static_cast<unsigned char>(*p);
    case Scalar::kI16:
      return std::bit_cast<std::int16_t>(load_bits<std::uint16_t>(p, swap));
    case Scalar::kU16:
      return load_bits<std::uint16_t>(p, swap);
    case Scalar::kI32:
      return std::bit_cast<std::int32_t>(load_bits<std::uint32_t>(p, swap));
    case Scalar::kU32:
      return load_bits<std::uint32_t>(p, swap);
    case Scalar::kI64:
      return static_cast<double>(std::bit_cast<std::int64_t>(load_bits<std::uint64_t>(p, swap)));
    case Scalar::kU64:
      return static_cast<double>(load_bits<std::uint64_t>(p, swap));
    case Scalar::kF32:
      return std::bit_cast<float>(load_bits<std::uint32_t>(p, swap));
    case Scalar::kF64:
      return std::bit_cast<double>(load_bits<std::uint64_t>(p, swap));
  }
  return 0.0;
}

// ---------------------------------------------------------------------------------------------
// Column roles and the cloud being built

enum Role : int { kX = 0, kY, kZ, kWeight, kObs, kRoleCount };
constexpr const char* kRoleName[kRoleCount] = {"x", "y", "z", "weight", "observations"};

int role_of(std::string_view name) {
  const std::string n = lower(name);
  if (n == "x") return kX;
  if (n == "y") return kY;
  if (n == "z") return kZ;
  if (n == "weight" || n == "confidence" || n == "quality") return kWeight;
  if (n == "observations" || n == "obs" || n == "count") return kObs;
  return -1;
}

/// Which column (field / property index) carries each role, -1 if none.
using RoleColumns = std::array<int, kRoleCount>;

/// Maps column names to roles. x, y, z must appear exactly once; the first weight-like and the
/// first count-like column are used. `usable(i)` says whether column i can carry a role
/// (e.g. PCD fields with COUNT 1); x/y/z in an unusable column is an error `why_unusable(i)`.
template <typename Usable, typename WhyUnusable>
RoleColumns assign_roles(const std::vector<std::string>& names, const std::string& file, int line,
                         std::string_view what, Usable usable, WhyUnusable why_unusable) {
  RoleColumns cols;
  cols.fill(-1);
  for (std::size_t i = 0; i < names.size(); ++i) {
    const int r = role_of(names[i]);
    if (r < 0) continue;
    const int idx = static_cast<int>(i);
    if (r <= kZ) {
      if (cols[static_cast<std::size_t>(r)] >= 0) {
        throw_input_error(file, line, "duplicate " + std::string(what) + " '" + names[i] + "'");
      }
      if (!usable(i)) throw_input_error(file, line, why_unusable(i));
    } else if (cols[static_cast<std::size_t>(r)] >= 0 || !usable(i)) {
      continue;
    }
    cols[static_cast<std::size_t>(r)] = idx;
  }
  for (int r = kX; r <= kZ; ++r) {
    if (cols[static_cast<std::size_t>(r)] < 0) {
      std::string have;
      for (std::size_t i = 0; i < names.size() && i < 12; ++i) {
        have += (i ? ", " : "") + printable(names[i]);
      }
      if (names.size() > 12) have += ", ...";
      throw_input_error(file, line,
                        "no '" + std::string(kRoleName[r]) + "' " + std::string(what) +
                            " (x, y and z are required; found: " +
                            (have.empty() ? std::string("none") : have) + ")");
    }
  }
  return cols;
}

class CloudBuilder {
 public:
  CloudBuilder(const std::string& name, const RoleColumns& cols, std::size_t reserve)
      : name_(name), has_weight_(cols[kWeight] >= 0), has_obs_(cols[kObs] >= 0) {
    cloud_.reserve(reserve);
    if (has_weight_) cloud_.weight.reserve(reserve);
    if (has_obs_) cloud_.observations.reserve(reserve);
  }

  /// One point; `v` holds the role values (unused roles ignored). `line` > 0 for text input,
  /// else errors name the 0-based point `index`.
  void add(const std::array<double, kRoleCount>& v, int line, std::size_t index) {
    constexpr double kFloatMax = std::numeric_limits<float>::max();
    for (int r = kX; r <= kZ; ++r) {
      if (!std::isfinite(v[static_cast<std::size_t>(r)]) ||
          std::abs(v[static_cast<std::size_t>(r)]) > kFloatMax) {
        ++skipped_;
        return;
      }
    }
    float w = 0.0F;
    std::uint16_t obs = 0;
    if (has_weight_) {
      const double d = v[kWeight];
      if (!std::isfinite(d) || std::abs(d) > kFloatMax)
        fail(line, index, "weight is not a finite float");
      w = static_cast<float>(d);
    }
    if (has_obs_) {
      const double d = v[kObs];
      if (!std::isfinite(d) || d < 0.0 || d != std::floor(d)) {
        fail(line, index, "observation count must be a non-negative integer");
      }
      obs = d >= 65535.0 ? std::uint16_t{65535} : static_cast<std::uint16_t>(d);
    }
    cloud_.x.push_back(static_cast<float>(v[kX]));
    cloud_.y.push_back(static_cast<float>(v[kY]));
    cloud_.z.push_back(static_cast<float>(v[kZ]));
    if (has_weight_) cloud_.weight.push_back(w);
    if (has_obs_) cloud_.observations.push_back(obs);
  }

  [[noreturn]] void fail(int line, std::size_t index, const std::string& msg) const {
    if (line > 0) throw_input_error(name_, line, msg);
    throw_input_error(name_, 0, "point " + std::to_string(index) + ": " + msg);
  }

  PointCloud finish(CloudReadStats* stats) {
    if (stats != nullptr) {
      stats->points_read = cloud_.size();
      stats->non_finite_skipped = skipped_;
    }
    return std::move(cloud_);
  }

 private:
  const std::string& name_;
  bool has_weight_;
  bool has_obs_;
  PointCloud cloud_;
  std::size_t skipped_ = 0;
};

/// Reserve for a text format: never more than the text could hold (a hostile header may claim
/// millions of points in a few bytes).
std::size_t text_reserve(std::uint64_t declared, std::size_t text_bytes) {
  return static_cast<std::size_t>(std::min<std::uint64_t>(declared, text_bytes / 6 + 1));
}

// ---------------------------------------------------------------------------------------------
// PLY

struct PlyProperty {
  std::string name;
  Scalar type = Scalar::kF32;  // item type for lists
  bool is_list = false;
  Scalar count_type = Scalar::kU8;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> props;
};

std::optional<Scalar> ply_type(std::string_view t) {
  if (t == "char" || t == "int8") return Scalar::kI8;
  if (t == "uchar" || t == "uint8") return Scalar::kU8;
  if (t == "short" || t == "int16") return Scalar::kI16;
  if (t == "ushort" || t == "uint16") return Scalar::kU16;
  if (t == "int" || t == "int32") return Scalar::kI32;
  if (t == "uint" || t == "uint32") return Scalar::kU32;
  if (t == "float" || t == "float32") return Scalar::kF32;
  if (t == "double" || t == "float64") return Scalar::kF64;
  return std::nullopt;
}

enum class PlyFormat { kNone, kAscii, kBinaryLe, kBinaryBe };

/// Skips one element that comes before "vertex" in a binary body, advancing `pos`.
void skip_binary_element(std::string_view bytes, std::size_t& pos, const PlyElement& e,
                         bool big_endian, const std::string& name) {
  const auto truncated = [&](std::uint64_t entry) {
    throw_input_error(name, 0,
                      "truncated: element '" + printable(e.name) + "' declares " +
                          std::to_string(e.count) + " entries, data ends in entry " +
                          std::to_string(entry));
  };
  const bool has_list =
      std::any_of(e.props.begin(), e.props.end(), [](const PlyProperty& p) { return p.is_list; });
  if (!has_list) {
    std::uint64_t row = 0;
    for (const PlyProperty& p : e.props) row += scalar_size(p.type);  // few properties, no overflow
    const auto total = checked_mul(row, e.count);
    if (!total || *total > bytes.size() - pos) {
      truncated(row == 0 ? 0 : (bytes.size() - pos) / row);
    }
    pos += static_cast<std::size_t>(*total);
    return;
  }
  // Lists: size every entry from its count (each entry consumes at least one byte, so this loop
  // is bounded by the input size whatever the declared count).
  for (std::uint64_t k = 0; k < e.count; ++k) {
    for (const PlyProperty& p : e.props) {
      if (!p.is_list) {
        if (scalar_size(p.type) > bytes.size() - pos) truncated(k);
        pos += scalar_size(p.type);
        continue;
      }
      const std::size_t cs = scalar_size(p.count_type);
      if (cs > bytes.size() - pos) truncated(k);
      const double n = load_scalar(bytes.data() + pos, p.count_type, big_endian);
      pos += cs;
      if (n < 0.0) {
        throw_input_error(name, 0,
                          "element '" + printable(e.name) + "' entry " + std::to_string(k) +
                              ": negative list length in property '" + printable(p.name) + "'");
      }
      const auto len = checked_mul(static_cast<std::uint64_t>(n), scalar_size(p.type));
      if (!len || *len > bytes.size() - pos) truncated(k);
      pos += static_cast<std::size_t>(*len);
    }
  }
}

}  // namespace

PointCloud parse_ply(std::string_view bytes, const std::string& name, CloudReadStats* stats) {
  if (bytes.empty()) throw_input_error(name, 0, "empty file");
  Lines lines(bytes);
  std::string_view line;
  lines.next(line);
  if (trim(line) != "ply") {
    throw_input_error(name, 1, "not a PLY file (the first line must be 'ply')");
  }

  PlyFormat format = PlyFormat::kNone;
  std::vector<PlyElement> elements;
  std::vector<std::string_view> tok;
  bool ended = false;
  while (lines.next(line)) {
    const int ln = lines.line();
    split_ws(line, tok);
    if (tok.empty()) continue;
    const std::string_view kw = tok[0];
    if (kw == "comment" || kw == "obj_info") continue;
    if (kw == "end_header") {
      if (tok.size() != 1) throw_input_error(name, ln, "malformed end_header line");
      ended = true;
      break;
    }
    if (kw == "format") {
      if (tok.size() != 3)
        throw_input_error(name, ln, "malformed format line (want 'format TYPE 1.0')");
      if (format != PlyFormat::kNone) throw_input_error(name, ln, "second format line");
      if (tok[1] == "ascii") {
        format = PlyFormat::kAscii;
      } else if (tok[1] == "binary_little_endian") {
        format = PlyFormat::kBinaryLe;
      } else if (tok[1] == "binary_big_endian") {
        format = PlyFormat::kBinaryBe;
      } else {
        throw_input_error(name, ln,
                          "unknown PLY format '" + printable(tok[1]) +
                              "' (want ascii, binary_little_endian or binary_big_endian)");
      }
      if (tok[2] != "1.0") {
        throw_input_error(name, ln,
                          "unsupported PLY version '" + printable(tok[2]) + "' (only 1.0)");
      }
    } else if (kw == "element") {
      if (tok.size() != 3)
        throw_input_error(name, ln, "malformed element line (want 'element NAME COUNT')");
      PlyElement e;
      e.name = std::string(tok[1]);
      if (!parse_u64(tok[2], e.count)) {
        throw_input_error(name, ln, "bad element count '" + printable(tok[2]) + "'");
      }
      if (e.name == "vertex") {
        for (const PlyElement& prev : elements) {
          if (prev.name == "vertex") throw_input_error(name, ln, "second 'vertex' element");
        }
        if (e.count > kMaxCloudPoints) {
          throw_input_error(name, ln,
                            "element vertex declares " + std::to_string(e.count) +
                                " points, more than the limit of " +
                                std::to_string(kMaxCloudPoints));
        }
      }
      elements.push_back(std::move(e));
    } else if (kw == "property") {
      if (elements.empty()) throw_input_error(name, ln, "property line before any element line");
      PlyElement& e = elements.back();
      PlyProperty p;
      if (tok.size() == 5 && tok[1] == "list") {
        const auto ct = ply_type(tok[2]);
        const auto it = ply_type(tok[3]);
        if (!ct || !it) {
          throw_input_error(name, ln,
                            "unknown property type '" + printable(ct ? tok[3] : tok[2]) + "'");
        }
        if (!is_integer(*ct)) {
          throw_input_error(name, ln,
                            "list length type '" + printable(tok[2]) + "' is not an integer type");
        }
        p.is_list = true;
        p.count_type = *ct;
        p.type = *it;
        p.name = std::string(tok[4]);
        if (e.name == "vertex") {
          throw_input_error(
              name, ln,
              "list property '" + printable(p.name) + "' in element vertex is not supported");
        }
      } else if (tok.size() == 3 && tok[1] != "list") {
        const auto t = ply_type(tok[1]);
        if (!t) throw_input_error(name, ln, "unknown property type '" + printable(tok[1]) + "'");
        p.type = *t;
        p.name = std::string(tok[2]);
      } else {
        throw_input_error(name, ln,
                          "malformed property line (want 'property TYPE NAME' or "
                          "'property list COUNT_TYPE ITEM_TYPE NAME')");
      }
      e.props.push_back(std::move(p));
    } else {
      throw_input_error(name, ln, "unknown PLY header line '" + printable(kw) + "'");
    }
  }
  if (!ended) throw_input_error(name, 0, "truncated header: no end_header line");
  if (format == PlyFormat::kNone) throw_input_error(name, 0, "header has no format line");
  const auto vit = std::find_if(elements.begin(), elements.end(),
                                [](const PlyElement& e) { return e.name == "vertex"; });
  if (vit == elements.end()) throw_input_error(name, 0, "header has no 'element vertex' line");
  const PlyElement& vertex = *vit;
  std::vector<std::string> names;
  for (const PlyProperty& p : vertex.props) names.push_back(p.name);
  const RoleColumns cols = assign_roles(
      names, name, 0, "vertex property", [](std::size_t) { return true; },
      [](std::size_t) { return std::string(); });

  std::array<double, kRoleCount> v{};
  const std::size_t body = lines.pos();

  if (format == PlyFormat::kAscii) {
    CloudBuilder out(name, cols, text_reserve(vertex.count, bytes.size() - body));
    Lines data(bytes.substr(body), lines.line() + 1);
    for (auto e = elements.begin(); e != vit; ++e) {
      if (e->props.empty()) continue;
      for (std::uint64_t k = 0; k < e->count; ++k) {
        if (!data.next_nonblank(line)) {
          throw_input_error(name, data.line(),
                            "truncated: element '" + printable(e->name) + "' declares " +
                                std::to_string(e->count) + " entries, found " + std::to_string(k));
        }
      }
    }
    const std::size_t nprops = vertex.props.size();
    for (std::uint64_t i = 0; i < vertex.count; ++i) {
      if (!data.next_nonblank(line)) {
        throw_input_error(name, data.line(),
                          "truncated: element vertex declares " + std::to_string(vertex.count) +
                              " points, found " + std::to_string(i));
      }
      split_ws(line, tok);
      if (tok.size() != nprops) {
        throw_input_error(name, data.line(),
                          "expected " + std::to_string(nprops) + " vertex values, found " +
                              std::to_string(tok.size()));
      }
      for (std::size_t c = 0; c < nprops; ++c) {
        double d = 0.0;
        if (!parse_double(tok[c], d)) {
          throw_input_error(name, data.line(),
                            "bad number '" + printable(tok[c]) + "' for property '" +
                                printable(vertex.props[c].name) + "'");
        }
        for (int r = 0; r < kRoleCount; ++r) {
          if (cols[static_cast<std::size_t>(r)] == static_cast<int>(c))
            v[static_cast<std::size_t>(r)] = d;
        }
      }
      out.add(v, data.line(), static_cast<std::size_t>(i));
    }
    return out.finish(stats);
  }

  const bool big = format == PlyFormat::kBinaryBe;
  std::size_t pos = body;
  for (auto e = elements.begin(); e != vit; ++e) skip_binary_element(bytes, pos, *e, big, name);
  std::size_t row = 0;
  std::vector<std::size_t> offset;
  for (const PlyProperty& p : vertex.props) {
    offset.push_back(row);
    row += scalar_size(p.type);
  }
  const auto need = checked_mul(row, vertex.count);
  const std::size_t have = bytes.size() - pos;
  if (!need || *need > have) {
    throw_input_error(name, 0,
                      "truncated: " + std::to_string(vertex.count) + " vertices of " +
                          std::to_string(row) + " bytes need " +
                          (need ? std::to_string(*need) : std::string("too many")) +
                          " bytes, only " + std::to_string(have) + " follow");
  }
  CloudBuilder out(name, cols, static_cast<std::size_t>(vertex.count));
  for (std::size_t i = 0; i < vertex.count; ++i) {
    const char* p = bytes.data() + pos + i * row;
    for (int r = 0; r < kRoleCount; ++r) {
      const int c = cols[static_cast<std::size_t>(r)];
      if (c < 0) continue;
      const auto ci = static_cast<std::size_t>(c);
      v[static_cast<std::size_t>(r)] = load_scalar(p + offset[ci], vertex.props[ci].type, big);
    }
    out.add(v, 0, i);
  }
  return out.finish(stats);
}

// ---------------------------------------------------------------------------------------------
// LZF

std::string lzf_decompress(std::string_view in, std::size_t out_size, const std::string& name) {
  const auto fail = [&](const std::string& msg) {
    throw_input_error(name, 0, "corrupt LZF data: " + msg);
  };
  // The best LZF can do is 264 output bytes from a 3-byte back-reference: anything claiming
  // more is corrupt, and checking it first keeps a tiny hostile file from a huge allocation.
  if (checked_mul(in.size(), 88).value_or(std::numeric_limits<std::uint64_t>::max()) < out_size) {
    fail("declared size " + std::to_string(out_size) + " is impossible for " +
         std::to_string(in.size()) + " compressed bytes");
  }
  std::string out(out_size, '\0');
  const auto* ip = reinterpret_cast<const unsigned char*>(in.data());
  const std::size_t in_size = in.size();
  std::size_t i = 0;
  std::size_t o = 0;
  while (i < in_size) {
    const unsigned ctrl = ip[i++];
    if (ctrl < 32) {  // literal run of ctrl + 1 bytes
      const std::size_t len = ctrl + 1;
      if (len > in_size - i)
        fail("literal run past the end of the input at byte " + std::to_string(i - 1));
      if (len > out_size - o)
        fail("output longer than the declared " + std::to_string(out_size) + " bytes");
      std::memcpy(out.data() + o, ip + i, len);
      i += len;
      o += len;
      continue;
    }
    std::size_t len = ctrl >> 5;
    if (len == 7) {
      if (i >= in_size) fail("back-reference cut off at the end of the input");
      len += ip[i++];
    }
    if (i >= in_size) fail("back-reference cut off at the end of the input");
    const std::size_t back = ((static_cast<std::size_t>(ctrl) & 0x1FU) << 8) + ip[i++] + 1;
    if (back > o) {
      fail("back-reference to " + std::to_string(back) + " bytes back at output byte " +
           std::to_string(o));
    }
    len += 2;
    if (len > out_size - o)
      fail("output longer than the declared " + std::to_string(out_size) + " bytes");
    for (std::size_t k = 0; k < len; ++k, ++o) out[o] = out[o - back];  // may overlap
  }
  if (o != out_size) {
    fail("decompresses to " + std::to_string(o) + " bytes, the header says " +
         std::to_string(out_size));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// PCD

namespace {

struct PcdField {
  std::string name;
  std::uint64_t size = 0;
  char type = 0;
  std::uint64_t count = 1;
  Scalar scalar = Scalar::kF32;
  std::uint64_t byte_offset = 0;   // in a binary row
  std::uint64_t token_offset = 0;  // in an ascii row
};

std::optional<Scalar> pcd_scalar(char type, std::uint64_t size) {
  if (type == 'F' && size == 4) return Scalar::kF32;
  if (type == 'F' && size == 8) return Scalar::kF64;
  if (type == 'I' && size == 1) return Scalar::kI8;
  if (type == 'I' && size == 2) return Scalar::kI16;
  if (type == 'I' && size == 4) return Scalar::kI32;
  if (type == 'I' && size == 8) return Scalar::kI64;
  if (type == 'U' && size == 1) return Scalar::kU8;
  if (type == 'U' && size == 2) return Scalar::kU16;
  if (type == 'U' && size == 4) return Scalar::kU32;
  if (type == 'U' && size == 8) return Scalar::kU64;
  return std::nullopt;
}

std::uint32_t load_u32_le(const char* p) {
  return static_cast<std::uint32_t>(load_scalar(p, Scalar::kU32, false));
}

}  // namespace

PointCloud parse_pcd(std::string_view bytes, const std::string& name, CloudReadStats* stats) {
  if (bytes.empty()) throw_input_error(name, 0, "empty file");
  Lines lines(bytes);
  std::string_view line;
  std::vector<std::string_view> tok;
  std::vector<std::string> field_names;
  std::vector<std::uint64_t> sizes;
  std::vector<std::uint64_t> counts;
  std::string types;
  std::optional<std::uint64_t> width;
  std::optional<std::uint64_t> height;
  std::optional<std::uint64_t> points;
  int fields_line = 0;
  int sizes_line = 0;
  int types_line = 0;
  int counts_line = 0;
  int points_line = 0;
  std::string data;
  int data_line = 0;

  const auto one_number = [&](int ln, std::string_view key) {
    std::uint64_t n = 0;
    if (tok.size() != 2 || !parse_u64(tok[1], n)) {
      throw_input_error(name, ln, std::string(key) + " must be one non-negative integer");
    }
    return n;
  };
  const auto numbers = [&](int ln, std::string_view key, std::vector<std::uint64_t>& out) {
    out.clear();
    for (std::size_t i = 1; i < tok.size(); ++i) {
      std::uint64_t n = 0;
      if (!parse_u64(tok[i], n)) {
        throw_input_error(name, ln,
                          "bad " + std::string(key) + " entry '" + printable(tok[i]) + "'");
      }
      out.push_back(n);
    }
  };

  while (data.empty()) {
    if (!lines.next(line)) {
      throw_input_error(name, 0, "truncated header: no DATA line");
    }
    const int ln = lines.line();
    const std::string_view t = trim(line);
    if (t.empty() || t.front() == '#') continue;
    split_ws(t, tok);
    const std::string_view kw = tok[0];
    if (kw == "VERSION") {
      if (tok.size() != 2) throw_input_error(name, ln, "malformed VERSION line");
      const std::string_view ver = tok[1];
      if (ver != "0.7" && ver != ".7" && ver != "0.6" && ver != ".6") {
        throw_input_error(name, ln,
                          "unsupported PCD version '" + printable(ver) + "' (want 0.7 or 0.6)");
      }
    } else if (kw == "FIELDS" || kw == "COLUMNS") {
      field_names.assign(tok.begin() + 1, tok.end());
      fields_line = ln;
      if (field_names.empty()) throw_input_error(name, ln, "FIELDS names no field");
    } else if (kw == "SIZE") {
      numbers(ln, "SIZE", sizes);
      sizes_line = ln;
    } else if (kw == "TYPE") {
      types.clear();
      for (std::size_t i = 1; i < tok.size(); ++i) {
        if (tok[i].size() != 1) {
          throw_input_error(name, ln,
                            "bad TYPE entry '" + printable(tok[i]) + "' (want F, I or U)");
        }
        types += tok[i][0];
      }
      types_line = ln;
    } else if (kw == "COUNT") {
      numbers(ln, "COUNT", counts);
      counts_line = ln;
    } else if (kw == "WIDTH") {
      width = one_number(ln, "WIDTH");
    } else if (kw == "HEIGHT") {
      height = one_number(ln, "HEIGHT");
    } else if (kw == "POINTS") {
      points = one_number(ln, "POINTS");
      points_line = ln;
    } else if (kw == "VIEWPOINT") {
      // Sensor pose; not used. Checked for shape only.
      double d = 0.0;
      if (tok.size() != 8) throw_input_error(name, ln, "VIEWPOINT must have 7 numbers");
      for (std::size_t i = 1; i < tok.size(); ++i) {
        if (!parse_double(tok[i], d)) {
          throw_input_error(name, ln, "bad VIEWPOINT number '" + printable(tok[i]) + "'");
        }
      }
    } else if (kw == "DATA") {
      if (tok.size() != 2 ||
          (tok[1] != "ascii" && tok[1] != "binary" && tok[1] != "binary_compressed")) {
        throw_input_error(name, ln,
                          "unknown DATA type '" + printable(tok.size() > 1 ? tok[1] : "") +
                              "' (want ascii, binary or binary_compressed)");
      }
      data = std::string(tok[1]);
      data_line = ln;
    } else {
      throw_input_error(name, ln, "unknown PCD header line '" + printable(kw) + "'");
    }
  }

  // The field layout.
  if (field_names.empty()) throw_input_error(name, data_line, "header has no FIELDS line");
  const std::size_t nf = field_names.size();
  if (sizes.size() != nf) {
    throw_input_error(
        name, sizes_line ? sizes_line : data_line,
        "SIZE has " + std::to_string(sizes.size()) + " entries, FIELDS has " + std::to_string(nf));
  }
  if (types.size() != nf) {
    throw_input_error(
        name, types_line ? types_line : data_line,
        "TYPE has " + std::to_string(types.size()) + " entries, FIELDS has " + std::to_string(nf));
  }
  if (counts_line == 0) counts.assign(nf, 1);
  if (counts.size() != nf) {
    throw_input_error(name, counts_line,
                      "COUNT has " + std::to_string(counts.size()) + " entries, FIELDS has " +
                          std::to_string(nf));
  }
  std::vector<PcdField> fields(nf);
  std::uint64_t row_bytes = 0;
  std::uint64_t row_tokens = 0;
  for (std::size_t i = 0; i < nf; ++i) {
    PcdField& f = fields[i];
    f.name = field_names[i];
    f.size = sizes[i];
    f.type = types[i];
    f.count = counts[i];
    const auto s = pcd_scalar(f.type, f.size);
    if (!s) {
      throw_input_error(name, types_line,
                        "field '" + printable(f.name) + "' has unsupported TYPE/SIZE " +
                            printable(std::string(1, f.type)) + std::to_string(f.size) +
                            " (want F4, F8, I1/2/4/8 or U1/2/4/8)");
    }
    f.scalar = *s;
    if (f.count == 0)
      throw_input_error(name, counts_line, "field '" + printable(f.name) + "' has COUNT 0");
    f.byte_offset = row_bytes;
    f.token_offset = row_tokens;
    const auto fb = checked_mul(f.size, f.count);
    const auto rb = fb ? checked_add(row_bytes, *fb) : std::nullopt;
    const auto rt = checked_add(row_tokens, f.count);
    if (!rb || !rt) throw_input_error(name, counts_line, "field sizes overflow");
    row_bytes = *rb;
    row_tokens = *rt;
  }
  const RoleColumns cols = assign_roles(
      field_names, name, fields_line, "field", [&](std::size_t i) { return fields[i].count == 1; },
      [&](std::size_t i) {
        return "field '" + fields[i].name + "' has COUNT " + std::to_string(fields[i].count) +
               " (x, y and z must have COUNT 1)";
      });

  if (!width) throw_input_error(name, data_line, "header has no WIDTH line");
  const std::uint64_t h = height.value_or(1);
  const auto wh = checked_mul(*width, h);
  if (!wh) throw_input_error(name, data_line, "WIDTH x HEIGHT overflows");
  if (points && *points != *wh) {
    throw_input_error(
        name, points_line,
        "POINTS " + std::to_string(*points) + " is not WIDTH x HEIGHT = " + std::to_string(*wh));
  }
  const std::uint64_t n = *wh;
  if (n > kMaxCloudPoints) {
    throw_input_error(name, points_line ? points_line : data_line,
                      "declares " + std::to_string(n) + " points, more than the limit of " +
                          std::to_string(kMaxCloudPoints));
  }

  std::array<double, kRoleCount> v{};
  const std::size_t body = lines.pos();

  if (data == "ascii") {
    CloudBuilder out(name, cols, text_reserve(n, bytes.size() - body));
    Lines rows(bytes.substr(body), data_line + 1);
    for (std::uint64_t i = 0; i < n; ++i) {
      if (!rows.next_nonblank(line)) {
        throw_input_error(
            name, rows.line(),
            "truncated: POINTS is " + std::to_string(n) + ", found " + std::to_string(i) + " rows");
      }
      split_ws(line, tok);
      if (tok.size() != row_tokens) {
        throw_input_error(name, rows.line(),
                          "expected " + std::to_string(row_tokens) + " values, found " +
                              std::to_string(tok.size()));
      }
      for (const PcdField& f : fields) {
        for (std::uint64_t k = 0; k < f.count; ++k) {
          double d = 0.0;
          if (!parse_double(tok[static_cast<std::size_t>(f.token_offset + k)], d)) {
            throw_input_error(name, rows.line(),
                              "bad number '" +
                                  printable(tok[static_cast<std::size_t>(f.token_offset + k)]) +
                                  "' for field '" + printable(f.name) + "'");
          }
        }
      }
      for (int r = 0; r < kRoleCount; ++r) {
        const int c = cols[static_cast<std::size_t>(r)];
        if (c < 0) continue;
        double d = 0.0;
        parse_double(
            tok[static_cast<std::size_t>(fields[static_cast<std::size_t>(c)].token_offset)], d);
        v[static_cast<std::size_t>(r)] = d;
      }
      out.add(v, rows.line(), static_cast<std::size_t>(i));
    }
    return out.finish(stats);
  }

  const auto need = checked_mul(n, row_bytes);
  if (!need) throw_input_error(name, data_line, "POINTS x row size overflows");
  std::string_view payload = bytes.substr(body);
  std::string decompressed;
  if (data == "binary_compressed" && *need == 0 && payload.size() < 8) {
    payload = {};  // no points: the size words are optional
  } else if (data == "binary_compressed") {
    if (payload.size() < 8) {
      throw_input_error(name, 0, "truncated: binary_compressed data has no size words");
    }
    const std::uint32_t csize = load_u32_le(payload.data());
    const std::uint32_t usize = load_u32_le(payload.data() + 4);
    payload.remove_prefix(8);
    if (csize > payload.size()) {
      throw_input_error(name, 0,
                        "truncated: " + std::to_string(csize) +
                            " compressed bytes declared, only " + std::to_string(payload.size()) +
                            " follow");
    }
    if (usize != *need) {
      throw_input_error(name, 0,
                        "binary_compressed: uncompressed size " + std::to_string(usize) +
                            " is not POINTS x row size = " + std::to_string(*need));
    }
    if (*need > 0) decompressed = lzf_decompress(payload.substr(0, csize), usize, name);
    payload = decompressed;
  } else if (*need > payload.size()) {
    throw_input_error(name, 0,
                      "truncated: " + std::to_string(n) + " points of " +
                          std::to_string(row_bytes) + " bytes need " + std::to_string(*need) +
                          " bytes, only " + std::to_string(payload.size()) + " follow");
  }
  const bool columnwise = data == "binary_compressed";
  CloudBuilder out(name, cols, static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < n; ++i) {
    for (int r = 0; r < kRoleCount; ++r) {
      const int c = cols[static_cast<std::size_t>(r)];
      if (c < 0) continue;
      const PcdField& f = fields[static_cast<std::size_t>(c)];  // COUNT 1
      // Column-wise: field f's values for all points follow those of the fields before it.
      const std::size_t at = columnwise ? static_cast<std::size_t>(f.byte_offset * n + i * f.size)
                                        : static_cast<std::size_t>(i * row_bytes + f.byte_offset);
      v[static_cast<std::size_t>(r)] = load_scalar(payload.data() + at, f.scalar, false);
    }
    out.add(v, 0, i);
  }
  return out.finish(stats);
}

// ---------------------------------------------------------------------------------------------
// CSV / XYZ

PointCloud parse_xyz_csv(std::string_view text, const std::string& name, CloudReadStats* stats) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 byte order mark
  if (text.empty()) throw_input_error(name, 0, "empty file");
  Lines lines(text);
  std::string_view line;
  std::vector<std::string_view> tok;
  std::vector<std::string> col_names;
  bool comma = false;
  bool started = false;
  std::size_t ncols = 0;
  RoleColumns cols{};
  std::optional<CloudBuilder> out;
  std::array<double, kRoleCount> v{};
  std::size_t index = 0;

  while (lines.next(line)) {
    const int ln = lines.line();
    std::string_view t = trim(line);
    if (t.empty() || t.front() == '#') continue;
    if (!started) {
      started = true;
      const bool slashes = t.substr(0, 2) == "//";  // CloudCompare's "//X,Y,Z" header
      if (slashes) t = trim(t.substr(2));
      comma = t.find(',') != std::string_view::npos;
      comma ? split_comma(t, tok) : split_ws(t, tok);
      double d = 0.0;
      if (slashes || tok.empty() || !parse_double(tok[0], d)) {  // a header line
        for (std::string_view s : tok) col_names.emplace_back(s);
        cols = assign_roles(
            col_names, name, ln, "column", [](std::size_t) { return true; },
            [](std::size_t) { return std::string(); });
        ncols = tok.size();
        out.emplace(name, cols, text.size() / 16 + 1);
        continue;
      }
      ncols = tok.size();
      if (ncols < 3) {
        throw_input_error(name, ln,
                          "expected at least 3 columns (x, y, z), found " + std::to_string(ncols));
      }
      cols = {kX, kY, kZ, -1, -1};
      out.emplace(name, cols, text.size() / 16 + 1);
    } else {
      comma ? split_comma(t, tok) : split_ws(t, tok);
    }
    if (tok.size() != ncols) {
      throw_input_error(
          name, ln,
          "expected " + std::to_string(ncols) + " fields, found " + std::to_string(tok.size()));
    }
    for (int r = 0; r < kRoleCount; ++r) {
      const int c = cols[static_cast<std::size_t>(r)];
      if (c < 0) continue;
      const std::string_view s = tok[static_cast<std::size_t>(c)];
      if (!parse_double(s, v[static_cast<std::size_t>(r)])) {
        throw_input_error(
            name, ln,
            "bad number '" + printable(s) + "' in column " + std::to_string(c + 1) +
                (col_names.empty()
                     ? std::string(" (") + kRoleName[r] + ")"
                     : " ('" + printable(col_names[static_cast<std::size_t>(c)]) + "')"));
      }
    }
    if (index >= kMaxCloudPoints) {
      throw_input_error(name, ln,
                        "more than the limit of " + std::to_string(kMaxCloudPoints) + " points");
    }
    out->add(v, ln, index++);
  }
  if (!out) throw_input_error(name, 0, "no data (only blank or comment lines)");
  return out->finish(stats);
}

// ---------------------------------------------------------------------------------------------
// Files

PointCloud read_cloud(const std::filesystem::path& path, CloudReadStats* stats) {
  const std::string ext = lower(path.extension().string());
  PointCloud (*parse)(std::string_view, const std::string&, CloudReadStats*) = nullptr;
  if (ext == ".ply") {
    parse = &parse_ply;
  } else if (ext == ".pcd") {
    parse = &parse_pcd;
  } else if (ext == ".csv" || ext == ".txt" || ext == ".xyz") {
    parse = &parse_xyz_csv;
  } else {
    throw_input_error(path.string(), 0,
                      "unknown point cloud extension '" + printable(ext) +
                          "' (want .ply, .pcd, .csv, .txt or .xyz)");
  }
  const std::string bytes = recording::read_text_file(path);
  return parse(bytes, path.string(), stats);
}

namespace {
/// Writes `buf` to PATH.part and renames it into place (a file never looks complete early).
void write_file_via_part(const std::filesystem::path& path, const std::string& buf) {
  std::filesystem::path tmp = path;
  tmp += ".part";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f)
      throw_input_error(tmp.string(), 0, std::string("cannot create: ") + std::strerror(errno));
    f.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    f.close();
    if (!f)
      throw_input_error(tmp.string(), 0, std::string("write failed: ") + std::strerror(errno));
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec)
    throw_input_error(path.string(), 0,
                      "cannot rename " + tmp.filename().string() + ": " + ec.message());
}

void put_f32(char*& p, float f) {
  std::uint32_t u = std::bit_cast<std::uint32_t>(f);
  if constexpr (std::endian::native == std::endian::big) u = __builtin_bswap32(u);
  std::memcpy(p, &u, 4);
  p += 4;
}
}  // namespace

void write_ply_rgb(const std::filesystem::path& path, const PointCloud& cloud,
                   std::span<const std::array<std::uint8_t, 3>> rgb) {
  const std::size_t n = cloud.size();
  if (!cloud.consistent()) throw std::invalid_argument("write_ply_rgb: inconsistent point cloud");
  if (rgb.size() != n) {
    throw std::invalid_argument("write_ply_rgb: " + std::to_string(rgb.size()) + " colours for " +
                                std::to_string(n) + " points");
  }
  std::string buf =
      "ply\nformat binary_little_endian 1.0\ncomment written by wallar\nelement vertex " +
      std::to_string(n) +
      "\nproperty float x\nproperty float y\nproperty float z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  const std::size_t header = buf.size();
  buf.resize(header + n * 15);
  char* p = buf.data() + header;
  for (std::size_t i = 0; i < n; ++i) {
    put_f32(p, cloud.x[i]);
    put_f32(p, cloud.y[i]);
    put_f32(p, cloud.z[i]);
    for (std::uint8_t c : rgb[i]) *p++ = static_cast<char>(c);
  }

  write_file_via_part(path, buf);
}

void write_ply_map(const std::filesystem::path& path, const PointCloud& cloud,
                   std::span<const float> sigma_m) {
  const std::size_t n = cloud.size();
  if (!cloud.consistent()) throw std::invalid_argument("write_ply_map: inconsistent point cloud");
  if ((!sigma_m.empty() && sigma_m.size() != n) ||
      (cloud.has_observations() && cloud.observations.size() != n)) {
    throw std::invalid_argument("write_ply_map: sigma or observations not one per point");
  }
  std::string buf =
      "ply\nformat binary_little_endian 1.0\ncomment written by wallar: a sparse map\n"
      "element vertex " +
      std::to_string(n) +
      "\nproperty float x\nproperty float y\nproperty float z\nproperty float sigma\n"
      "property ushort observations\nend_header\n";
  const std::size_t header = buf.size();
  buf.resize(header + n * 18);
  char* p = buf.data() + header;
  for (std::size_t i = 0; i < n; ++i) {
    put_f32(p, cloud.x[i]);
    put_f32(p, cloud.y[i]);
    put_f32(p, cloud.z[i]);
    put_f32(p, sigma_m.empty() ? 0.0f : sigma_m[i]);
    std::uint16_t obs = cloud.has_observations() ? cloud.observations[i] : 0;
    if constexpr (std::endian::native == std::endian::big) obs = __builtin_bswap16(obs);
    std::memcpy(p, &obs, 2);
    p += 2;
  }
  write_file_via_part(path, buf);
}

}  // namespace wallar::cloud
