// SPDX-License-Identifier: Apache-2.0
/// @file study_map.cpp
/// @brief The appliance's final map as the real-data study's input.
#include "study_map.hpp"

#include "commands.hpp"
#include "wallar/core/error.hpp"
#include "wallar/firmware/offline.hpp"
#include "wallar/firmware/world_frames.hpp"

namespace wallar::cli {

eval::GivenMap appliance_map_for_study(const recording::EurocRecording& rec) {
  const firmware::ApplianceReport report = firmware::run_over_recording(
      rec, firmware::BoardConfig{}, firmware::offline_options(firmware::ApplianceMode::kLockStep),
      stop_requested());
  const firmware::PoseRecord* first = nullptr;
  for (const firmware::PoseRecord& r : report.trajectory) {
    if (r.rejected == nullptr && r.state == dsp::TrackingState::kTracking) {
      first = &r;
      break;
    }
  }
  if (first == nullptr || !report.map) {
    throw InputError(rec.mav0.string() + ": the appliance tracked no frame of the recording");
  }
  // Tracker's world -> the raw left camera at the first tracked frame.
  const SE3d T_world_cam0 = first->T_world_body * rec.rig().cams[0].T_body_cam;
  eval::GivenMap map;
  map.points = firmware::transformed(report.map->points, T_world_cam0.inverse());
  map.t_ns = first->t_ns;
  map.frames = report.frames_tracked;
  map.description = "the appliance's tracker and mapper, lock step, " +
                    std::to_string(report.map_keyframes) + " key-frame" +
                    (report.map_keyframes == 1 ? "" : "s");
  return map;
}

}  // namespace wallar::cli
