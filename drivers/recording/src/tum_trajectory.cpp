// SPDX-License-Identifier: Apache-2.0
/// @file tum_trajectory.cpp
/// @brief TUM trajectory text: lossless time stamps, strict line-numbered parsing.
#include "wallar/drivers/recording/tum_trajectory.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include "wallar/core/error.hpp"

namespace wallar::recording {
namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r'; }

// Decimal seconds -> nanoseconds without going through a double (epoch-sized stamps have 19
// significant digits). Accepts [-]digits[.digits]; other forms (exponents) via double.
std::optional<TimeNs> parse_seconds(std::string_view s) {
  if (s.empty()) return std::nullopt;
  const bool negative = s.front() == '-';
  std::string_view body = negative || s.front() == '+' ? s.substr(1) : s;
  const std::size_t dot = body.find('.');
  const std::string_view whole = body.substr(0, dot);
  const std::string_view frac =
      dot == std::string_view::npos ? std::string_view{} : body.substr(dot + 1);
  auto digits = [](std::string_view d) {
    for (char c : d) {
      if (c < '0' || c > '9') return false;
    }
    return true;
  };
  if (digits(whole) && digits(frac) && !(whole.empty() && frac.empty())) {
    std::int64_t sec = 0;
    if (!whole.empty()) {
      const auto [ptr, ec] = std::from_chars(whole.data(), whole.data() + whole.size(), sec);
      if (ec != std::errc() || ptr != whole.data() + whole.size()) return std::nullopt;
    }
    if (sec > std::numeric_limits<std::int64_t>::max() / kNsPerS - 1) return std::nullopt;
    std::int64_t ns = 0;
    for (std::size_t i = 0; i < 9; ++i) ns = ns * 10 + (i < frac.size() ? frac[i] - '0' : 0);
    if (frac.size() > 9 && frac[9] >= '5') ++ns;  // round half up on the 10th decimal
    const TimeNs t = sec * kNsPerS + ns;
    return negative ? -t : t;
  }
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(value) ||
      std::abs(value) > 9e9) {
    return std::nullopt;
  }
  return static_cast<TimeNs>(std::llround(value * 1e9));
}

}  // namespace

std::string format_tum(std::span<const StampedPose> poses) {
  std::string out;
  out.reserve(poses.size() * 96);
  std::array<char, 256> buf{};
  for (const StampedPose& p : poses) {
    Eigen::Quaterniond q(p.T_world_body.linear());
    q.normalize();
    if (q.w() < 0) q.coeffs() = -q.coeffs();
    const Eigen::Vector3d& t = p.T_world_body.translation();
    const TimeNs mag = p.t_ns < 0 ? -p.t_ns : p.t_ns;
    const int n = std::snprintf(
        buf.data(), buf.size(), "%s%lld.%09lld %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n",
        p.t_ns < 0 ? "-" : "", static_cast<long long>(mag / kNsPerS),
        static_cast<long long>(mag % kNsPerS), t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    out.append(buf.data(), static_cast<std::size_t>(n));
  }
  return out;
}

std::vector<StampedPose> parse_tum(std::string_view text, std::string_view source_name) {
  std::vector<StampedPose> out;
  std::size_t pos = 0;
  int line = 0;
  while (pos < text.size()) {
    ++line;
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    std::string_view raw = text.substr(pos, eol - pos);
    pos = eol + 1;
    while (!raw.empty() && is_space(raw.front())) raw.remove_prefix(1);
    while (!raw.empty() && is_space(raw.back())) raw.remove_suffix(1);
    if (raw.empty() || raw.front() == '#') continue;
    std::array<std::string_view, 8> fields;
    std::size_t count = 0;
    std::size_t i = 0;
    while (i < raw.size()) {
      while (i < raw.size() && is_space(raw[i])) ++i;
      const std::size_t start = i;
      while (i < raw.size() && !is_space(raw[i])) ++i;
      if (i > start) {
        if (count < fields.size()) fields[count] = raw.substr(start, i - start);
        ++count;
      }
    }
    if (count != 8) {
      throw_input_error(source_name, line,
                        "expected 8 fields 't x y z qx qy qz qw', got " + std::to_string(count));
    }
    const auto t_ns = parse_seconds(fields[0]);
    if (!t_ns) {
      throw_input_error(source_name, line,
                        "time must be a number of seconds, got '" + printable(fields[0]) + "'");
    }
    std::array<double, 7> v{};
    static constexpr std::array<const char*, 7> kNames = {"x", "y", "z", "qx", "qy", "qz", "qw"};
    for (std::size_t k = 0; k < 7; ++k) {
      const std::string_view f = fields[k + 1];
      const auto [ptr, ec] = std::from_chars(f.data(), f.data() + f.size(), v[k]);
      if (ec != std::errc() || ptr != f.data() + f.size() || !std::isfinite(v[k])) {
        throw_input_error(
            source_name, line,
            std::string(kNames[k]) + " must be a finite number, got '" + printable(f) + "'");
      }
    }
    const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (std::abs(q.norm() - 1.0) > 0.01) {
      throw_input_error(source_name, line,
                        "quaternion norm " + std::to_string(q.norm()) + " is not 1");
    }
    if (!out.empty() && *t_ns <= out.back().t_ns) {
      throw_input_error(source_name, line,
                        "time " + std::string(fields[0]) + " s is not after the previous line's");
    }
    out.push_back({*t_ns, make_se3(q, Eigen::Vector3d(v[0], v[1], v[2]))});
  }
  return out;
}

}  // namespace wallar::recording
