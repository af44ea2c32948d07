// SPDX-License-Identifier: Apache-2.0
/// @file tracking_support.hpp
/// @brief Helpers shared by the tracker's tests.
///
/// Threading: test-thread only.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "wallar/core/image.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/stereo_frame.hpp"
#include "wallar/core/time.hpp"
#include "wallar/dsp/tracking/features.hpp"
#include "wallar/dsp/tracking/fixed_vector.hpp"
#include "wallar/dsp/tracking/gray_image.hpp"
#include "wallar/dsp/tracking/synthetic_motion.hpp"
#include "wallar/dsp/tracking/synthetic_room.hpp"

namespace wallar::test {

/// Seeded doubles from raw mt19937_64 outputs (std:: distributions differ across standard
/// libraries, so a test's figures would too).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : gen_(seed) {}
  double uniform() { return static_cast<double>(gen_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  double gaussian() {  // Box-Muller
    const double u1 = 1.0 - uniform(), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }
  Eigen::Vector3d direction() {
    Eigen::Vector3d d(gaussian(), gaussian(), gaussian());
    return d.normalized();
  }

 private:
  std::mt19937_64 gen_;
};

/// The tracker's view of a gray image (no copy: `img` must outlive it).
inline dsp::GrayView gray_view(const Image& img) {
  return {img.data(), img.width(), img.height(), img.stride_bytes()};
}

/// The detector's corners (default parameters, no features tracked yet) of a whole image, at
/// most `max_corners`.
inline dsp::FixedVector<dsp::Corner> detect_corners(const Image& img, std::size_t max_corners) {
  dsp::CornerDetector detector(img.width(), img.height(), dsp::DetectorParams{});
  std::vector<std::uint16_t> occupancy(static_cast<std::size_t>(detector.bucket_count()), 0);
  dsp::FixedVector<dsp::Corner> corners(max_corners);
  detector.detect(gray_view(img), occupancy, corners);
  return corners;
}

/// The room small enough that its walls are 2-3 m from the path (EuRoC-like rig).
using dsp::small_room;

/// Both eyes of `cam` rendered in `room` at T_world_cam, stamped `t_ns`.
inline StereoFrame stereo(const dsp::SyntheticRoom& room, const dsp::SyntheticCamera& cam,
                          const SE3d& T_world_cam, TimeNs t_ns) {
  StereoFrame f;
  f.t_ns = t_ns;
  f.left.t_ns = f.right.t_ns = t_ns;
  f.left.image = dsp::render_room_image(room, cam, T_world_cam, 0);
  f.right.image = dsp::render_room_image(room, cam, T_world_cam, 1);
  return f;
}

}  // namespace wallar::test
