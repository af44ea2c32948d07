// SPDX-License-Identifier: Apache-2.0
/// @file head_pivot.cpp
/// @brief The head's lever from its pivot by forgetting least squares on velocity changes.
#include "wallar/dsp/tracking/head_pivot.hpp"

#include <Eigen/Cholesky>
#include <cmath>

namespace wallar::dsp {

void HeadPivot::reset() {
  count_ = 0;
  H_.setZero();
  b_.setZero();
  lever_cam_.setZero();
}

void HeadPivot::observe(TimeNs t_ns, const SE3d& T_cam_world, bool learn) {
  Sample s;
  s.t_ns = t_ns;
  s.R_world_cam = T_cam_world.linear().transpose();
  s.c_world = -s.R_world_cam * T_cam_world.translation();
  if (count_ > 0 && t_ns <= history_[static_cast<std::size_t>((count_ - 1) % 3)].t_ns) {
    count_ = 0;  // time went backwards or stood still: start over
  }
  history_[static_cast<std::size_t>(count_ % 3)] = s;
  ++count_;
  if (count_ < 3 || !learn) return;
  const Sample& s0 = history_[static_cast<std::size_t>((count_ - 3) % 3)];
  const Sample& s1 = history_[static_cast<std::size_t>((count_ - 2) % 3)];
  const Sample& s2 = history_[static_cast<std::size_t>((count_ - 1) % 3)];
  const double dt1 = ns_to_s(s1.t_ns - s0.t_ns), dt2 = ns_to_s(s2.t_ns - s1.t_ns);
  // Rates of the centre and of the rotation matrix over the two steps.
  const Eigen::Vector3d a = (s2.c_world - s1.c_world) / dt2 - (s1.c_world - s0.c_world) / dt1;
  const Eigen::Matrix3d A =
      (s2.R_world_cam - s1.R_world_cam) / dt2 - (s1.R_world_cam - s0.R_world_cam) / dt1;
  const double keep = std::exp(-dt2 / params_.memory_s);
  H_ = keep * H_ + A.transpose() * A;
  b_ = keep * b_ + A.transpose() * a;
  const Eigen::Matrix3d N = H_ + params_.prior_weight * Eigen::Matrix3d::Identity();
  const Eigen::Vector3d l = N.ldlt().solve(b_);
  if (!l.allFinite()) return;
  const double n = l.norm();
  lever_cam_ = n > params_.max_lever_m ? Eigen::Vector3d(l * (params_.max_lever_m / n)) : l;
}

}  // namespace wallar::dsp
