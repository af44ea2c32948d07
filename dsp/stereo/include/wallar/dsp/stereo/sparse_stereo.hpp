// SPDX-License-Identifier: Apache-2.0
/// @file sparse_stereo.hpp
/// @brief A sparse 3-D cloud from one rectified stereo pair: ORB features matched across the
/// pair along rectified rows and triangulated. A stand-in for the tracker's map (issue 7) so
/// that walls can be found in real recordings today.
///
/// Threading: a SparseStereo is used by one thread; construct once per rig (rectification
/// maps are computed in the constructor).
#pragma once

#include <opencv2/core.hpp>
#include <span>

#include "wallar/core/calibration.hpp"
#include "wallar/core/image.hpp"
#include "wallar/core/point_cloud.hpp"
#include "wallar/core/stereo_frame.hpp"
#include "wallar/dsp/stereo/rectifier.hpp"

namespace wallar::dsp {

struct SparseStereoParams {
  int max_features = 3000;
  double max_row_error_px = 1.5;  //!< |y_left - y_right| after rectification
  double min_depth_m = 0.3;
  double max_depth_m = 8.0;
  int max_hamming = 50;  //!< ORB descriptor distance
};

struct SparseStereoStats {
  std::size_t features_left = 0, features_right = 0, matches = 0, triangulated = 0;
};

class SparseStereo {
 public:
  SparseStereo(const RigCalibration& rig, SparseStereoParams params = {});

  /// Points in the (unrectified) left camera frame: x right, y down, z forward [m].
  PointCloud triangulate(const Image& left, const Image& right, SparseStereoStats* stats = nullptr);

  [[nodiscard]] double baseline_m() const { return rectifier_.baseline_m(); }

 private:
  SparseStereoParams params_;
  Rectifier rectifier_;
};

/// A sparse map of several stereo pairs, all in the first pair's left camera frame.
struct SparseMap {
  PointCloud points;
  std::size_t pairs_used = 0;
};

/// Triangulates `pairs` in order and merges their points. Merging is only right when the
/// camera did not move between the pairs (`still`, e.g. from the IMU); otherwise only the first
/// pair is used.
SparseMap build_sparse_map(SparseStereo& stereo, std::span<const StereoFrame> pairs, bool still);

}  // namespace wallar::dsp
