// SPDX-License-Identifier: Apache-2.0
/// @file reconstruction.cpp
/// @brief The wall search over the tracker's map and the thread that repeats it.
#include "wallar/firmware/appliance/reconstruction.hpp"

#include <algorithm>

#include "wallar/firmware/appliance/allocation_count.hpp"

namespace wallar::firmware {

const char* to_string(RoomGravity gravity) {
  switch (gravity) {
    case RoomGravity::kImu:
      return "2-D (gravity from the IMU)";
    case RoomGravity::kPath:
      return "2-D (down from the path over the ground)";
    case RoomGravity::kNone:
      break;
  }
  return "3-D (no gravity)";
}

Reconstruction::Reconstruction(const ReconstructionOptions& options, std::size_t max_points,
                               TripleBuffer<WallModel>& out)
    : options_(options), estimator_(std::max<std::size_t>(max_points, 1)), out_(out) {}

bool Reconstruction::maybe_run(const dsp::MapSnapshot& map,
                               const std::optional<Eigen::Vector3d>& imu_down, std::uint32_t epoch,
                               bool force) {
  // Without the IMU's gravity, a path over the ground gives it (a drive, a walk).
  const std::optional<Eigen::Vector3d> path_down =
      imu_down ? std::nullopt : dsp::down_from_path(map);
  const std::optional<Eigen::Vector3d>& down = imu_down ? imu_down : path_down;
  const RoomGravity gravity =
      imu_down ? RoomGravity::kImu : (path_down ? RoomGravity::kPath : RoomGravity::kNone);
  if (epoch != epoch_) {  // the map was reset: the old walls are no warm start
    epoch_ = epoch;
    previous_.reset();
    last_points_ = 0;
  }
  const std::size_t n = map.points.size();
  if (n < options_.min_map_points) return false;
  const bool grown =
      last_points_ == 0 || static_cast<double>(n) >=
                               static_cast<double>(last_points_) * (1.0 + options_.regrow_fraction);
  // Down arriving (the attitude filter's first gravity, or a path long enough) or going makes
  // another search, grown or not: a 3-D search cannot tell the floor from a wall, and a still
  // head's map may never grow by regrow_fraction to bring the next one.
  const bool gravity_changed = runs_ > 0 && gravity != last_gravity_;
  if (!grown && !gravity_changed && !(force && n != last_points_)) return false;
  dsp::local_map(map, options_.local_radius_m, local_);
  if (local_.points.size() < options_.min_map_points) return false;
  const double threshold =
      std::max(options_.threshold_m, options_.threshold_sigmas * local_.median_sigma_m);
  dsp::RoomConfig config =
      dsp::room_config_for_map(local_.viewpoints, down, threshold, options_.max_surfaces);
  config.detector.method = options_.method;
  config.detector.seed = options_.seed + runs_;
  const TimeNs t0 = monotonic_now_ns();
  dsp::RoomResult result =
      estimator_.estimate(local_.points, config, previous_ ? &*previous_ : nullptr);
  time_.record(monotonic_now_ns() - t0);
  previous_ = result.model;
  last_points_ = n;
  last_gravity_ = gravity;
  ++runs_;
  out_.back() = result.model;
  out_.publish();
  for (TripleBuffer<WallModel>* o : more_outs_) {
    if (o == nullptr) continue;
    o->back() = result.model;
    o->publish();
  }
  result_ = std::move(result);
  return true;
}

ReconstructionThread::ReconstructionThread(Reconstruction& reconstruction,
                                           TripleBuffer<MapPtr>& maps,
                                           const Seqlock<PoseSnapshot>& pose, DurationNs period_ns,
                                           ThreadSpec spec, const std::atomic<bool>& stop)
    : timer_(period_ns), thread_(std::move(spec), [this, &reconstruction, &maps, &pose, &stop] {
        tl_allocation_counter = &allocations_;
        MapPtr map;
        while (!stop.load(std::memory_order_acquire)) {
          timer_.wait();
          heartbeat_.beat(monotonic_now_ns());
          wakeups_.fetch_add(1, std::memory_order_relaxed);
          if (maps.refresh()) map = maps.front();
          if (!map) continue;
          const PoseSnapshot p = pose.load();
          reconstruction.maybe_run(*map, down_of(p), p.epoch, false);
        }
        tl_allocation_counter = nullptr;
      }) {}

}  // namespace wallar::firmware
