// SPDX-License-Identifier: Apache-2.0
/// @file reconstruction.hpp
/// @brief The reconstruction module: walls, floor and ceiling of the tracker's map, searched
/// again when the map grew (RoomEstimator, warm-started from the last model so ids are kept),
/// 2-D with the IMU's gravity, 3-D without; each model published on the wall model's
/// TripleBuffer.
///
/// Reconstruction is the search itself; ReconstructionThread runs it periodically on the
/// reconstruct thread from the map channel and the pose channel's gravity (real time and every
/// frame). In lock step the tracking thread calls Reconstruction::maybe_run() itself after
/// key-frames instead, so the walls come at fixed points of the stream.
///
/// Threading: Reconstruction is not thread-safe: one thread at a time (the reconstruct thread,
/// or the tracking thread in lock step; the supervisor after both stopped). ReconstructionThread
/// is built, stopped and read by the supervisor; its counters from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>

#include "wallar/core/heartbeat.hpp"
#include "wallar/core/seqlock.hpp"
#include "wallar/core/triple_buffer.hpp"
#include "wallar/dsp/tracking/mapper.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/firmware/appliance/snapshots.hpp"
#include "wallar/firmware/latency_histogram.hpp"
#include "wallar/firmware/periodic.hpp"
#include "wallar/firmware/rt_thread.hpp"

namespace wallar::firmware {

struct ReconstructionOptions {
  dsp::ScoreMethod method = dsp::RoomConfig{}.detector.method;  //!< the room search's default
  double threshold_m = 0.04;  //!< inlier band of the tracker's map (at least)
  /// The search looks at the map within this of the newest key-frame (dsp::local_map): all of
  /// a room, the stretch of street around a moving rig.
  double local_radius_m = 25.0;
  /// The inlier band widens to this many times the local points' median uncertainty (a map of
  /// facades 10-20 m away is not as tight as a room's).
  double threshold_sigmas = 1.5;
  int max_surfaces = 6;
  double regrow_fraction = 0.10;          //!< re-run when the map grew by this share ...
  std::size_t min_map_points = 60;        //!< ... and has at least this many points
  std::uint64_t seed = 1;                 //!< wall search seeds (seed + run index)
  DurationNs period_ns = 200 * kNsPerMs;  //!< the reconstruct thread's period
};

/// Where the wall search's "down" came from.
enum class RoomGravity : std::uint8_t {
  kNone,  //!< 3-D search
  kImu,   //!< 2-D search, gravity from the attitude filter
  kPath,  //!< 2-D search, down from the key-frames' path over the ground (no IMU)
};
/// "3-D (no gravity)", "2-D (gravity from the IMU)", "2-D (down from the path)".
const char* to_string(RoomGravity gravity);

class Reconstruction {
 public:
  Reconstruction(const ReconstructionOptions& options, std::size_t max_points,
                 TripleBuffer<WallModel>& out);
  /// Each model is also published on `more` (the live server's, the client API's channels: up
  /// to kMaxMoreOuts, each with its own reader); before any run.
  void also_publish_to(TripleBuffer<WallModel>* more) {
    for (TripleBuffer<WallModel>*& o : more_outs_) {
      if (o == nullptr) {
        o = more;
        return;
      }
    }
    throw std::logic_error("Reconstruction: more than kMaxMoreOuts outputs");
  }
  static constexpr std::size_t kMaxMoreOuts = 2;

  /// Runs when the map grew enough since the last run or the gravity mode changed (down arrived
  /// or went), or with `force` whenever the map changed; returns whether it ran. A new `epoch` (a
  /// reset) forgets the last model. `imu_down` is gravity from the IMU in the map's frame; without
  /// it, the key-frames' path gives it when it runs over the ground (dsp::down_from_path), else the
  /// search is 3-D.
  bool maybe_run(const dsp::MapSnapshot& map, const std::optional<Eigen::Vector3d>& imu_down,
                 std::uint32_t epoch, bool force);

  [[nodiscard]] const std::optional<dsp::RoomResult>& result() const { return result_; }
  [[nodiscard]] RoomGravity gravity() const { return last_gravity_; }
  [[nodiscard]] std::uint64_t runs() const { return runs_; }
  [[nodiscard]] const LatencyHistogram& time() const { return time_; }

 private:
  ReconstructionOptions options_;
  dsp::RoomEstimator estimator_;
  TripleBuffer<WallModel>& out_;
  TripleBuffer<WallModel>* more_outs_[kMaxMoreOuts] = {};
  std::optional<WallModel> previous_;
  std::optional<dsp::RoomResult> result_;
  std::size_t last_points_ = 0;
  RoomGravity last_gravity_ = RoomGravity::kNone;
  dsp::LocalMap local_;  //!< the part of the map searched (capacity kept between runs)
  std::uint32_t epoch_ = 0;
  std::uint64_t runs_ = 0;
  LatencyHistogram time_;
};

/// The reconstruct thread: every period, the newest map and gravity into `reconstruction`.
/// Allocations are counted, not required to be zero: the search builds its result (a
/// background module like mapping; tracking never waits for it).
class ReconstructionThread {
 public:
  ReconstructionThread(Reconstruction& reconstruction, TripleBuffer<MapPtr>& maps,
                       const Seqlock<PoseSnapshot>& pose, DurationNs period_ns, ThreadSpec spec,
                       const std::atomic<bool>& stop);
  /// Joins the thread (after `stop` was set).
  void join() { thread_.join(); }
  [[nodiscard]] const RtThread& thread() const { return thread_; }
  [[nodiscard]] std::uint64_t wakeups() const { return wakeups_.load(std::memory_order_relaxed); }
  /// Periods missed (read after join).
  [[nodiscard]] std::uint64_t misses() const { return timer_.misses(); }
  [[nodiscard]] const std::atomic<std::uint64_t>& allocations() const { return allocations_; }
  /// A loop: beats at each period, so a wall search that never returns reads as silent.
  [[nodiscard]] const Heartbeat& heartbeat() const { return heartbeat_; }

 private:
  PeriodicTimer timer_;
  Heartbeat heartbeat_{Heartbeat::Kind::kLoop, monotonic_now_ns()};
  std::atomic<std::uint64_t> wakeups_{0};
  std::atomic<std::uint64_t> allocations_{0};
  RtThread thread_;  // last: starts once the rest is built
};

}  // namespace wallar::firmware
