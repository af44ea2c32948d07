// SPDX-License-Identifier: Apache-2.0
/// @file loop_shift.cpp
/// @brief Time stamps moved on by a loop's offset.
#include "wallar/firmware/hil/loop_shift.hpp"

namespace wallar::firmware::hil {

void LoopShift::on_imu(const ImuSample& s) {
  if (offset_ns_ == 0) return next_.on_imu(s);
  ImuSample shifted = s;
  shifted.t_ns += offset_ns_;
  next_.on_imu(shifted);
}

void LoopShift::on_stereo(const StereoFrame& f) {
  if (offset_ns_ == 0) return next_.on_stereo(f);
  StereoFrame shifted = f;  // counted references: no pixels copied
  shifted.t_ns += offset_ns_;
  shifted.left.t_ns += offset_ns_;
  shifted.right.t_ns += offset_ns_;
  next_.on_stereo(shifted);
}

}  // namespace wallar::firmware::hil
