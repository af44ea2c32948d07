// SPDX-License-Identifier: Apache-2.0
/// @file point_cloud.hpp
/// @brief A sparse 3-D point cloud in structure-of-arrays float layout (SIMD friendly).
///
/// x, y, z are separate contiguous arrays so kernels stream one coordinate at a time. weight
/// and observation count are optional columns: empty, or as long as x.
///
/// Threading: not synchronised; share it read-only (e.g. as a published snapshot).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace wallar {

struct PointCloud {
  std::vector<float> x;                     //!< [m], in `frame`
  std::vector<float> y;                     //!< [m]
  std::vector<float> z;                     //!< [m]
  std::vector<float> weight;                //!< optional per-point quality, empty if none
  std::vector<std::uint16_t> observations;  //!< optional observation count, empty if none

  [[nodiscard]] std::size_t size() const { return x.size(); }
  [[nodiscard]] bool empty() const { return x.empty(); }
  [[nodiscard]] bool has_weight() const { return !weight.empty(); }
  [[nodiscard]] bool has_observations() const { return !observations.empty(); }

  void reserve(std::size_t n) {
    x.reserve(n);
    y.reserve(n);
    z.reserve(n);
  }
  void clear() {
    x.clear();
    y.clear();
    z.clear();
    weight.clear();
    observations.clear();
  }
  void push_back(const Eigen::Vector3f& p) {
    x.push_back(p.x());
    y.push_back(p.y());
    z.push_back(p.z());
  }
  [[nodiscard]] Eigen::Vector3f point(std::size_t i) const { return {x[i], y[i], z[i]}; }

  /// True when every optional column is either empty or as long as the coordinates.
  [[nodiscard]] bool consistent() const {
    const std::size_t n = x.size();
    return y.size() == n && z.size() == n && (weight.empty() || weight.size() == n) &&
           (observations.empty() || observations.size() == n);
  }
};

}  // namespace wallar
