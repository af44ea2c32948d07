// SPDX-License-Identifier: Apache-2.0
/// @file live_publisher.hpp
/// @brief The live module (`wallar run --live [ADDR:]PORT`, or the board's `live:`): the
/// appliance's outputs served over Foxglove's WebSocket protocol (drivers/net's FoxgloveServer)
/// as they happen, so Foxglove (or any client of the protocol) shows the head, the map, the
/// walls and the cameras of a running headset.
///
/// Channels (Foxglove's published schemas, firmware/foxglove_messages.hpp), frames "world" (the
/// tracker's), "body", "cam0", "cam1" and "up" (the world turned so +z is against gravity, once
/// the attitude filter has it: pick it as the 3-D panel's display frame):
///   /pose        foxglove.PoseInFrame      the body in the world, at most 20 Hz
///   /tf          foxglove.FrameTransforms  up -> world, world -> body, body -> cam0, cam1
///   /trajectory  foxglove.PosesInFrame     the body's path (thinned to a pose per 5 cm/5 deg)
///   /map         foxglove.PointCloud       the sparse map, coloured by surface, at most 2 Hz
///   /walls       foxglove.SceneUpdate      walls, floor and ceiling as each search ends
///   /cam0 /cam1  foxglove.CompressedImage  JPEG, `image_rate_hz` per camera, when subscribed
///   /stats       wallar.Stats              threads and stages (`wallar run --stats`), 1 Hz
///   /log         foxglove.Log              the firmware's log lines (the last 200 kept)
///
/// Never in a fixed-rate thread's way: the module reads the pose from its seqlock, the map and
/// the walls from triple buffers of their own (one reader each: this thread), and the frames
/// from a newest-only mailbox the tracking thread posts to only when an image is due (a flag it
/// reads; posting copies two image references, no pixels, and never blocks or allocates).
/// Encoding (JSON, base64, JPEG) happens on this thread (SCHED_OTHER, "live"), sending on the
/// server's; a client that reads slowly loses messages (newest wins), counted in /stats.
///
/// Threading: built, started and stopped by the supervisor (its thread); offer_frame() from the
/// tracking thread only; log() from any thread (the log thread); counters from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/core/mailbox.hpp"
#include "wallar/core/seqlock.hpp"
#include "wallar/core/stereo_frame.hpp"
#include "wallar/core/triple_buffer.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/drivers/net/foxglove_server.hpp"
#include "wallar/firmware/appliance/records.hpp"
#include "wallar/firmware/appliance/snapshots.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/rt_thread.hpp"

namespace wallar::firmware {

/// The stats rows now (the supervisor's live_rows/stage_rows), called on the live thread.
using StatsSource = std::function<void(std::vector<ThreadRow>&, std::vector<StageRow>&)>;

struct LivePublisherOptions {
  DurationNs pose_period_ns = 50 * kNsPerMs;    //!< the loop: pose and transforms
  DurationNs scene_period_ns = 500 * kNsPerMs;  //!< map and trajectory at most this often
  DurationNs stats_period_ns = 1 * kNsPerS;
  std::size_t max_trajectory_poses = 4096;  //!< beyond, every other pose is dropped
  std::size_t log_history = 200;            //!< log lines kept for a client that connects
};

class LivePublisher {
 public:
  /// Reads the token file and listens (before any module thread starts): throws InputError
  /// naming the token file or ADDRESS:PORT when it cannot. Clients may connect from here on
  /// (they get serverInfo and the channels); messages come once start() ran.
  LivePublisher(const LiveConfig& config, const RigCalibration& rig, LivePublisherOptions options,
                const Seqlock<PoseSnapshot>& pose, TripleBuffer<MapPtr>& maps,
                TripleBuffer<WallModel>& walls);
  ~LivePublisher();  // stop()s
  LivePublisher(const LivePublisher&) = delete;
  LivePublisher& operator=(const LivePublisher&) = delete;

  /// Starts the live thread; `stats` is called on it once per stats period (may be empty).
  void start(ThreadSpec spec, StatsSource stats);
  /// Stops the thread and closes every connection (idempotent); no stats call after it.
  void stop();
  /// After stop(): what ended the live thread early (an exception), or empty.
  [[nodiscard]] std::string error() const {
    return thread_ && thread_->failed() ? thread_->error() : std::string();
  }

  /// Tracking thread, per frame tracked: posts `frame` when an image is due (a client
  /// subscribes to a camera and the image period has passed). Never blocks or allocates.
  void offer_frame(const StereoFrame& frame) {
    if (!image_due_.load(std::memory_order_relaxed)) return;
    image_due_.store(false, std::memory_order_relaxed);
    frames_.post(frame);
  }
  /// A log line, on /log (allocates; not for a fixed-rate thread). Dropped after stop().
  void log(const std::string& line);

  /// "ws://127.0.0.1:8765/" (the port the kernel chose when the board said 0).
  [[nodiscard]] std::string url() const;
  /// The start-up log line: where to connect, and a warning when a network address has no
  /// token.
  [[nodiscard]] std::string describe() const;
  [[nodiscard]] const RtThread* thread() const { return thread_.get(); }
  [[nodiscard]] net::FoxgloveServerStats server_stats() const { return server_.stats(); }
  /// Images encoded and published (both cameras counted).
  [[nodiscard]] std::uint64_t images() const { return images_.load(std::memory_order_relaxed); }
  /// The live server's counters as (name, value), for /stats and the run's report.
  [[nodiscard]] std::vector<std::pair<const char*, std::uint64_t>> counters() const;

 private:
  void loop(const std::atomic<bool>& stop);
  void publish_pose(const PoseSnapshot& p);
  void publish_scene(TimeNs t_ns, bool walls_changed);
  void publish_images(const StereoFrame& frame);

  LiveConfig config_;
  LivePublisherOptions options_;
  const Seqlock<PoseSnapshot>& pose_;
  TripleBuffer<MapPtr>& maps_;
  TripleBuffer<WallModel>& walls_;
  SE3d T_body_cam_[2];
  net::FoxgloveServer server_;
  struct Channels {
    std::uint32_t pose, tf, trajectory, map, walls, cam[2], stats, log;
  } ch_{};
  StatsSource stats_;

  NewestMailbox<StereoFrame> frames_;
  std::atomic<bool> image_due_{false};
  std::atomic<std::uint64_t> images_{0};
  std::atomic<TimeNs> sensor_now_ns_{0};  //!< the newest pose's time: the stamp of the rest

  // The live thread's own.
  TimeNs last_pose_t_ns_ = -1;
  std::uint32_t epoch_ = 0;
  std::vector<SE3d> trajectory_;
  bool trajectory_changed_ = false;
  std::uint64_t map_version_ = 0;
  bool map_changed_ = false;
  TimeNs next_scene_ns_ = 0, next_stats_ns_ = 0, next_image_ns_ = 0;
  std::vector<ThreadRow> thread_rows_;
  std::vector<StageRow> stage_rows_;

  std::mutex log_mutex_;  // log() against stop()
  bool serving_ = false;  // guarded by log_mutex_
  std::atomic<bool> stop_{false};
  std::unique_ptr<RtThread> thread_;
};

}  // namespace wallar::firmware
