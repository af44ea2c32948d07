// SPDX-License-Identifier: Apache-2.0
/// @file reconstruction.cpp
/// @brief The wall search over the tracker's map and the thread that repeats it.
#include "wallar/firmware/appliance/reconstruction.hpp"

#include <algorithm>

#include "wallar/firmware/appliance/allocation_count.hpp"

namespace wallar::firmware {

Reconstruction::Reconstruction(const ReconstructionOptions& options, std::size_t max_points,
                               TripleBuffer<WallModel>& out)
    : options_(options), estimator_(std::max<std::size_t>(max_points, 1)), out_(out) {}

bool Reconstruction::maybe_run(const dsp::MapSnapshot& map,
                               const std::optional<Eigen::Vector3d>& down, std::uint32_t epoch,
                               bool force) {
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
  if (!grown && !(force && n != last_points_) && !(force && down.has_value() != last_gravity_)) {
    return false;
  }
  dsp::RoomConfig config = dsp::room_config_for_map(map.keyframe_centres, down,
                                                    options_.threshold_m, options_.max_surfaces);
  config.detector.method = options_.method;
  config.detector.seed = options_.seed + runs_;
  const TimeNs t0 = monotonic_now_ns();
  dsp::RoomResult result =
      estimator_.estimate(map.points, config, previous_ ? &*previous_ : nullptr);
  time_.record(monotonic_now_ns() - t0);
  previous_ = result.model;
  last_points_ = n;
  last_gravity_ = down.has_value();
  ++runs_;
  out_.back() = result.model;
  out_.publish();
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
          wakeups_.fetch_add(1, std::memory_order_relaxed);
          if (maps.refresh()) map = maps.front();
          if (!map) continue;
          const PoseSnapshot p = pose.load();
          reconstruction.maybe_run(*map, down_of(p), p.epoch, false);
        }
        tl_allocation_counter = nullptr;
      }) {}

}  // namespace wallar::firmware
