// SPDX-License-Identifier: Apache-2.0
/// @file client_server.hpp
/// @brief The client API server (`wallar run --client-socket PATH`, the board's `client:`):
/// applications (libwallar-client, firmware/client/) get the head pose from a shared-memory
/// seqlock and the planes with OpenXR's semantics over a UNIX stream socket. The protocol is
/// client/include/wallar/client/wire.hpp; docs/architecture.md ("Client API") describes it.
///
/// Pieces:
///   SharedPosePublisher  the tracking thread's writer of the memfd's pose seqlock: the newest
///                        pose, velocity, and the bias-corrected gyro integrated since the pose
///                        (updated for each IMU sample the tracking thread drains).
///   ClientPlanes         wall models -> OpenXR planes and change events (ids from the
///                        reconstruction; merges derived here: subsumed_by).
///   ClientServer         the socket, the memfd and the "client" thread (SCHED_OTHER, thread
///                        table): poll() over the listening socket and the clients, bounded
///                        per-client queues, dropped updates counted, never in a fixed-rate
///                        thread's way (it reads the pose seqlock and a triple buffer of its own).
///
/// Threading: ClientServer is built, started and stopped by the supervisor; publisher() is used
/// by the tracking thread only (one writer); counters() from any thread. ClientPlanes and
/// plane_record() are plain values and pure functions.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "wallar/client/wire.hpp"
#include "wallar/core/pose.hpp"
#include "wallar/core/seqlock.hpp"
#include "wallar/core/triple_buffer.hpp"
#include "wallar/core/wall.hpp"
#include "wallar/firmware/appliance/snapshots.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/rt_thread.hpp"

namespace wallar::firmware {

/// The tracking thread's writer of the shared pose. Allocation-free, never waits. Poses come
/// in the tracker's world and leave in the first body pose's (T_out_world).
class SharedPosePublisher {
 public:
  SharedPosePublisher() = default;
  /// T_body_view: the view apps render from (the rectified left camera in the body frame).
  SharedPosePublisher(client_wire::SharedPoseBlock* block, const SE3d& T_out_world,
                      const SE3d& T_body_view);

  /// A tracked (or held) pose: resets the gyro integration to it. `sensor_minus_monotonic_ns`
  /// maps the sensors' clock to CLOCK_MONOTONIC (0 when unknown).
  void on_pose(TimeNs t_ns, const SE3d& T_world_body, client_wire::Tracking state,
               std::uint32_t epoch, DurationNs sensor_minus_monotonic_ns);
  /// An IMU sample after the pose: its bias-corrected angular rate in the body frame.
  void on_imu(TimeNs t_ns, const Eigen::Vector3d& omega_body_rad_s);
  [[nodiscard]] bool attached() const { return writer_.attached(); }

 private:
  client_wire::SharedPoseWriter writer_;
  SE3d T_out_world_ = SE3d::Identity();
  client_wire::PosePayload value_;
  Eigen::Quaterniond q_pose_imu_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_prev_ = Eigen::Vector3d::Zero();
  TimeNs t_prev_ns_ = -1;
  std::uint32_t epoch_prev_ = 0;
};

/// Wall models in, plane changes out. A wall's id is the plane's (the reconstruction keeps
/// ids across updates, warm-started); a plane that disappears while a plane of the new model
/// lies on it is reported removed with subsumed_by set (the merge rule, kSubsume*).
class ClientPlanes {
 public:
  static constexpr double kSubsumeAngleDeg = 10.0;   //!< normals within this
  static constexpr double kSubsumeDistanceM = 0.10;  //!< and offsets within this
  static constexpr double kSubsumeMarginM = 0.20;    //!< centre within the polygon grown by this

  /// The changes from the last model to `model` (world: the API's); `down_world` (gravity)
  /// decides orientations when known. An epoch change (a reset) removes every plane first.
  client_wire::PlaneBatch update(const WallModel& model,
                                 const std::optional<Eigen::Vector3d>& down_world);
  /// Every current plane, as added (a new client's first batch, or a resync).
  [[nodiscard]] client_wire::PlaneBatch full() const;
  [[nodiscard]] std::size_t size() const { return planes_.size(); }

 private:
  struct Kept {
    client_wire::PlaneRecord record;
    Wall wall;
  };
  std::map<std::uint32_t, Kept> planes_;
  std::uint64_t model_version_ = 0;
  TimeNs t_ns_ = 0;
};

/// One wall as an API plane (change kAdded, change_count 0). `gravity_aligned`: the wall's
/// model was found knowing down (WallModel::gravity_aligned); without it the semantic is
/// unknown, and so is the orientation unless `down_world` gives it.
client_wire::PlaneRecord plane_record(const Wall& wall,
                                      const std::optional<Eigen::Vector3d>& down_world,
                                      bool gravity_aligned);
/// Whether `absorbed` lies on `survivor` (the merge rule of ClientPlanes).
bool subsumes(const Wall& survivor, const Wall& absorbed);

struct ClientServerOptions {
  DurationNs loop_period_ns = 10 * kNsPerMs;  //!< poll timeout: tracking state, walls
  std::size_t max_queue_bytes = 1u << 20;     //!< per client; beyond, updates are dropped
  DurationNs hello_timeout_ns = 2 * kNsPerS;  //!< a connection without a hello is closed
  int max_clients = 32;
};

/// Counters, all since start.
struct ClientServerCounters {
  std::uint64_t accepted = 0;   //!< hellos accepted
  std::uint64_t refused = 0;    //!< version mismatch or not allowed (SO_PEERCRED)
  std::uint64_t malformed = 0;  //!< closed for a bad, unexpected or oversized message
  std::uint64_t timeouts = 0;   //!< closed without a hello
  std::uint64_t dropped = 0;    //!< updates not queued for a client (queue full)
  std::uint64_t resyncs = 0;    //!< full plane sets sent after drops
  std::uint64_t sent_bytes = 0;
  std::uint64_t clients = 0;       //!< connected now
  std::uint64_t plane_models = 0;  //!< wall models turned into plane batches
};

class ClientServer {
 public:
  /// Creates the socket (mode and group from `config`; a stale socket file is replaced, a live
  /// one or another file at the path is an InputError) and the memfd, before any module
  /// thread starts. T_out_world: the tracker's world into the API's (the first body pose);
  /// T_body_view: the view apps render from (the rectified left camera in the body frame).
  ClientServer(const ClientConfig& config, const SE3d& T_out_world, const SE3d& T_body_view,
               const Seqlock<PoseSnapshot>& pose, TripleBuffer<WallModel>& walls,
               ClientServerOptions options = {});
  ~ClientServer();  // stop()s, unlinks the socket
  ClientServer(const ClientServer&) = delete;
  ClientServer& operator=(const ClientServer&) = delete;

  /// The tracking thread's writer (shared memory, no system call).
  [[nodiscard]] SharedPosePublisher& publisher() { return publisher_; }
  void start(ThreadSpec spec);
  /// Takes the newest wall model once more, gives clients up to `flush_ns` to read what is
  /// queued, then closes every connection and stops the thread (idempotent).
  void stop(DurationNs flush_ns = 300 * kNsPerMs);
  [[nodiscard]] const RtThread* thread() const { return thread_.get(); }
  [[nodiscard]] std::string error() const {
    return thread_ && thread_->failed() ? thread_->error() : std::string();
  }
  [[nodiscard]] std::string describe() const;
  [[nodiscard]] ClientServerCounters counters() const;
  /// counters() as (name, value) for the run's report and the stats note.
  [[nodiscard]] std::vector<std::pair<const char*, std::uint64_t>> counter_list() const;
  [[nodiscard]] const std::string& path() const { return config_.socket; }
  /// The client thread's loop passes (the stats table's wake-ups).
  [[nodiscard]] std::uint64_t wakeups() const { return wakeups_.load(std::memory_order_relaxed); }

 private:
  struct Client;
  void loop();
  void step(bool final_pass);
  void accept_clients();
  void read_client(Client& c);
  void close_client(Client& c, std::atomic<std::uint64_t>* counter);
  void queue(Client& c, const std::vector<std::uint8_t>& msg, bool plane_update);
  void flush(Client& c);
  void hello(Client& c, const std::uint8_t* body, std::size_t n);

  ClientConfig config_;
  ClientServerOptions options_;
  SE3d T_out_world_;
  SE3d T_body_view_;
  const Seqlock<PoseSnapshot>& pose_;
  TripleBuffer<WallModel>& walls_;
  int listen_fd_ = -1;
  int memfd_ = -1;
  int wake_fd_ = -1;  //!< eventfd: stop()
  void* shm_ = nullptr;
  unsigned gid_ = 0;
  bool has_group_ = false;
  std::string group_note_;
  SharedPosePublisher publisher_;

  // The client thread's own.
  std::vector<std::unique_ptr<Client>> clients_;
  ClientPlanes planes_;
  std::uint8_t tracking_sent_ = 0xff;
  std::vector<std::uint8_t> msg_;

  std::atomic<std::uint64_t> accepted_{0}, refused_{0}, malformed_{0}, timeouts_{0}, dropped_{0},
      resyncs_{0}, sent_bytes_{0}, clients_now_{0}, plane_models_{0}, wakeups_{0};
  std::atomic<bool> stop_{false};
  std::atomic<DurationNs> flush_ns_{0};
  std::unique_ptr<RtThread> thread_;
};

}  // namespace wallar::firmware
