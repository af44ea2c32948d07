// SPDX-License-Identifier: Apache-2.0
/// @file marker_none.cpp
/// @brief Builds without OpenCV contrib (the device build): the marker functions report that
/// ArUco is absent. Dictionary names, view poses and planes still work (marker.cpp).
#include <stdexcept>

#include "wallar/eval/marker.hpp"

namespace wallar::eval {
namespace {

[[noreturn]] void no_aruco() {
  throw std::runtime_error(
      "ArUco marker support is not in this build (OpenCV contrib is host-only)");
}

}  // namespace

bool aruco_available() { return false; }

Image render_marker_view(const CameraCalibration& /*cam*/,
                         const Eigen::Isometry3d& /*T_cam_marker*/, const MarkerSpec& /*spec*/,
                         double /*noise_sigma*/, std::uint64_t /*seed*/) {
  no_aruco();
}

std::optional<MarkerEstimate> estimate_marker_plane(const Image& /*gray*/,
                                                    const CameraCalibration& /*cam*/,
                                                    const MarkerSpec& /*spec*/) {
  no_aruco();
}

}  // namespace wallar::eval
