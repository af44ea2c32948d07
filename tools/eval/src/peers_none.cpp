// SPDX-License-Identifier: Apache-2.0
/// @file peers_none.cpp
/// @brief Builds without PCL and Open3D (device builds, and the unit tests, which need neither):
/// the peers report their absence.
#include <stdexcept>

#include "wallar/eval/peers.hpp"

namespace wallar::eval {

bool peers_available() { return false; }

PeerFit fit_plane_peer(Peer /*peer*/, const PointCloud& /*cloud*/, double /*threshold_m*/,
                       std::uint32_t /*max_rounds*/, double /*probability*/,
                       std::uint64_t /*seed*/) {
  throw std::runtime_error(
      "PCL and Open3D are not in this build (host builds with WALLAR_WITH_PEERS=ON have them)");
}

}  // namespace wallar::eval
