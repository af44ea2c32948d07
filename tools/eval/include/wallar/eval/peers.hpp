// SPDX-License-Identifier: Apache-2.0
/// @file peers.hpp
/// @brief What users would otherwise pick, on the evaluation's own scenes: PCL 1.13's
/// SACSegmentation (SACMODEL_PLANE, SAC_RANSAC, coefficients refined) and Open3D's
/// PointCloud::SegmentPlane, both plain RANSAC. Host builds only (WALLAR_HAVE_PEERS); elsewhere
/// peers_available() is false and fit_plane_peer() throws.
///
/// Threading: call from one thread at a time (Open3D's random generator and OpenMP settings are
/// process-wide; Open3D runs on one thread here so a seed gives one answer).
#pragma once

#include <cstdint>
#include <string_view>

#include "wallar/core/plane.hpp"
#include "wallar/core/point_cloud.hpp"

namespace wallar::eval {

enum class Peer : std::uint8_t { kPcl, kOpen3d };

struct PeerFit {
  bool found = false;
  Plane plane;  //!< n toward the origin (the viewpoint)
  std::uint32_t inliers = 0;
};

/// True when this build links PCL and Open3D.
bool peers_available();

/// The peer's best plane with inlier band threshold_m, at most max_rounds samples and its
/// early stop at `probability` (eq. 2.7's p). Open3D is seeded with `seed`; PCL has no seed
/// (it starts from the same state on every call). Throws std::runtime_error without peers.
PeerFit fit_plane_peer(Peer peer, const PointCloud& cloud, double threshold_m,
                       std::uint32_t max_rounds, double probability, std::uint64_t seed);

}  // namespace wallar::eval
