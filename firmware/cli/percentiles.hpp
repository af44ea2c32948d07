// SPDX-License-Identifier: Apache-2.0
/// @file percentiles.hpp
/// @brief Mean, p50, p99 and max of nanosecond durations, in milliseconds, for the commands'
/// timing reports.
///
/// Threading: pure functions.
#pragma once

#include <algorithm>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <vector>

namespace wallar::cli {

struct Percentiles {
  double mean_ms = 0, p50_ms = 0, p99_ms = 0, max_ms = 0;
};

inline Percentiles percentiles(std::vector<std::int64_t> v) {
  Percentiles p;
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  double sum = 0;
  for (std::int64_t x : v) sum += static_cast<double>(x);
  const auto at = [&](double q) {
    const auto i = static_cast<std::size_t>(q * static_cast<double>(v.size()));
    return static_cast<double>(v[std::min(v.size() - 1, i)]) * 1e-6;
  };
  p.mean_ms = sum / static_cast<double>(v.size()) * 1e-6;
  p.p50_ms = at(0.5);
  p.p99_ms = at(0.99);
  p.max_ms = static_cast<double>(v.back()) * 1e-6;
  return p;
}

inline nlohmann::json to_json(const Percentiles& p) {
  return {{"mean_ms", p.mean_ms}, {"p50_ms", p.p50_ms}, {"p99_ms", p.p99_ms}, {"max_ms", p.max_ms}};
}

}  // namespace wallar::cli
