// SPDX-License-Identifier: Apache-2.0
/// @file appliance.hpp
/// @brief The appliance (thesis fig. 3.3-3.4): the supervisor that builds every module from a
/// board file, couples their channels, runs them on the threads of one table, watches their
/// health and stops them in two phases. Every command that tracks runs it: `wallar run` in
/// real time, `wallar track`, `render` and `eval real` over a recording, as fast as tracking
/// goes.
///
/// Modules (firmware/appliance/) and channels:
///
///   source module (replay_module | live_module) ──ImuSample──▶ SpscRing ─┐ (pipeline_sink)
///        │                                      ──StereoFrame─▶ NewestMailbox + Wakeup
///        ▼
///   tracking thread (tracking_thread): attitude filter, TrackingAndMapping (tracker front end;
///        mapper on the mapping thread or in lock step), degraded modes ──pose──▶ Seqlock
///        │ map ─▶ TripleBuffer ─▶ reconstruct thread (reconstruction) ──walls──▶ TripleBuffer
///        │ ViewPost ─▶ NewestMailbox ─▶ render thread (LiveView)  ◀──────────────────┘
///   supervisor (this call's thread, periodic): stop/exit/reset (inputs), SIGUSR1 stats
///   (stats), health, systemd watchdog.
///
/// Modes (ApplianceMode): real time (the sensors' pace; the newest frame is tracked, older ones
/// overwritten and counted); every frame (replay only: the replay waits until tracking took each
/// frame, mapping on its thread, reconstruction periodic: `wallar track`); lock step (replay
/// only: every frame, mapping on the tracking thread after each key-frame, reconstruction at
/// fixed points: bit-identical from run to run for a seed; `wallar track --lockstep`, `wallar
/// run --deterministic`, `render`, `eval real`).
///
/// Worlds: the modules work in the tracker's world (its first rectified left camera); the
/// report's trajectory, map and walls are in that world, and T_body_rect takes them into the
/// first body pose's, the world of the commands' files (offline.hpp).
///
/// Threading: run_appliance() is called from one thread, which becomes the supervisor; `stop`
/// and `stats_request` may be set from any thread or a signal handler.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "wallar/core/pose.hpp"
#include "wallar/drivers/input/evdev_keys.hpp"
#include "wallar/drivers/source/async_recorder.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/firmware/appliance/allocation_count.hpp"
#include "wallar/firmware/appliance/reconstruction.hpp"
#include "wallar/firmware/appliance/records.hpp"
#include "wallar/firmware/appliance/replay_module.hpp"
#include "wallar/firmware/appliance/source_module.hpp"
#include "wallar/firmware/appliance/stats.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/live_view.hpp"
#include "wallar/firmware/tracking_and_mapping.hpp"

namespace wallar::firmware {

enum class ApplianceMode : std::uint8_t {
  kRealTime,    //!< the sensors' pace: newest frame tracked, mapping thread, periodic walls
  kEveryFrame,  //!< replay only: no frame overwritten, mapping thread, periodic walls
  kLockStep,    //!< replay only: every frame, mapping and walls in lock step (repeatable)
};
const char* to_string(ApplianceMode mode);

struct ApplianceOptions {
  ApplianceMode mode = ApplianceMode::kRealTime;
  source::ReplayOptions replay;  //!< replay boards: rate, offset, skip
  /// Test tooling (firmware/hil: loops, injected faults), made for the recording at start;
  /// empty: the recording is played once, as it is.
  std::function<std::unique_ptr<ReplayPlan>(const recording::EurocRecording&)> replay_plan;
  /// Test tooling (firmware/hil's tracking-hang fault): called on the tracking thread before
  /// each frame, with the frame's time; empty in the product.
  std::function<void(TimeNs t_ns)> before_frame;
  /// Test tooling (firmware/hil's render-hang fault): called on the render thread before each
  /// draw, inside the draw's heartbeat; empty in the product.
  std::function<void(TimeNs now_ns)> before_draw;
  DurationNs max_duration_ns = 0;  //!< > 0: stop after this much wall time
  bool view = true;                //!< draw the headset view (render thread)
  std::filesystem::path png_dir;   //!< write every `png_every`th drawn view here (empty: none)
  int png_every = 0;
  /// Draw this wall model (in the first body pose's world) instead of the reconstruction's.
  std::optional<WallModel> view_walls;
  bool use_gyro = true;  //!< the gyro's rotation as the tracker's prior
  /// Adjusts the tracker and mapper settings made from the board file before they are used
  /// (benchmarks and tests: capacities, thresholds); empty: the board's.
  std::function<void(TrackingOptions&)> adjust_tracking;
  dsp::ScoreMethod wall_method = dsp::RoomConfig{}.detector.method;
  double wall_threshold_m = 0.04;  //!< inlier band of the tracker's map
  int max_surfaces = 6;
  DurationNs reconstruct_period_ns = 200 * kNsPerMs;
  double regrow_fraction = 0.10;     //!< re-run when the map grew by this share ...
  std::size_t min_map_points = 60;   //!< ... and has at least this many points
  DurationNs camera_timeout_ns = 0;  //!< 0: max(4 frame periods, 200 ms)
  DurationNs imu_timeout_ns = 100 * kNsPerMs;
  DurationNs supervisor_period_ns = 100 * kNsPerMs;
  DurationNs rss_sample_period_ns = 1 * kNsPerS;  //!< resident memory sampled this often
  std::size_t max_records = 1 << 16;              //!< per-frame records kept (55 min at 20 Hz)
  bool realtime = true;    //!< SCHED_FIFO, affinity, mlockall where permitted
  std::uint64_t seed = 1;  //!< wall search seeds (seed + run index)
  std::string input_keys;  //!< evdev keyboard ("/dev/input/eventN", "name:..."), or none
  /// Tests and embedders (the VIT library's reset): one more input beside the board's, asked
  /// by the supervisor at every tick (its thread) when the board's gave nothing.
  std::function<drivers::InputAction(TimeNs now_ns)> test_input;
  /// Embedders (the VIT library): each frame's outcome, called on the tracking thread right
  /// after the frame (tracked, lost or rejected); must return quickly and never block.
  std::function<void(const FramePose&)> on_frame_pose;
  /// Also hand every sample the source delivers to this recorder (`wallar run --record`; its
  /// rings never block: a full ring drops, counted); null: none. It outlives the run.
  source::AsyncRecorder* record = nullptr;
  /// One line per event (start, transitions, warnings); default: stderr.
  std::function<void(const std::string&)> log;
};

struct ApplianceReport {
  std::string source;  //!< what was started
  std::string display;
  ApplianceMode mode = ApplianceMode::kRealTime;
  source::ReplayStats replay;  //!< summed over loops
  int loops_played = 0;
  std::optional<dsp::RoomResult> room;            //!< the last wall model (tracker's world)
  RoomGravity room_gravity = RoomGravity::kNone;  //!< the last search's down (2-D) or none
  std::uint64_t reconstructions = 0;
  std::size_t map_points = 0, map_keyframes = 0;
  /// The final map (after a global adjustment), tracker's world.
  std::shared_ptr<const dsp::MapSnapshot> map;
  /// The tracker's world (its first rectified left camera) into the first body pose's world.
  SE3d T_body_rect = SE3d::Identity();
  TrackingCounters tracking;
  std::vector<std::int64_t> mapping_times_ns;  //!< each local bundle adjustment
  DegradedCounters degraded;
  /// One record per frame the tracking module took, tracked, lost or rejected (tracker's
  /// world), up to ApplianceOptions::max_records.
  std::vector<PoseRecord> trajectory;
  bool imu = false;  //!< IMU samples reached tracking (false: a vision-only run)
  std::uint64_t imu_samples = 0, imu_dropped = 0;
  std::uint64_t frames_in = 0, frames_overwritten = 0, frames_tracked = 0;
  LiveViewStats view;
  /// The live server (board live:, `wallar run --live`): its URL (empty: off) and counters.
  std::string live_url;
  std::vector<std::pair<const char*, std::uint64_t>> live;
  /// The client API (board client:, `wallar run --client-socket`): its socket (empty: off)
  /// and counters (ClientServer::counter_list()).
  std::string client_socket;
  std::vector<std::pair<const char*, std::uint64_t>> client;
  /// The live devices' driver counters at the end (SourceModule::device_counters()).
  std::vector<std::pair<std::string, std::string>> devices;
  std::vector<std::string> events;  //!< transitions and warnings, in order
  std::vector<ThreadRow> threads;
  std::vector<StageRow> stages;
  bool memory_locked = false;
  DurationNs wall_time_ns = 0;
  long max_rss_kb = 0;
  std::vector<long> rss_kb;  //!< resident memory every rss_sample_period_ns (the soak's check)
  std::string stop_reason;   //!< "end of replay", "signal", "exit key", "time limit", ...
  bool interrupted = false;  //!< by a signal or the exit input
};

/// Builds the modules of `board`, runs them until the source ends, `stop` is set, the exit
/// input fires or the time limit passes, and returns the report. Throws InputError (bad
/// board, recording or calibration; an unreadable image during the replay) or
/// DeviceError/DisplayError (a device that cannot be opened); errors of a module thread are
/// rethrown after the others were stopped.
ApplianceReport run_appliance(const BoardConfig& board, const ApplianceOptions& options,
                              const std::atomic<bool>& stop,
                              std::atomic<bool>* stats_request = nullptr);

/// The appliance fed by `source` (a PushModule: samples pushed from outside, the VIT library;
/// the caller's, started by this call and joined before it returns) on the rig `rig`
/// (`rig_source` names it in errors), sized by `board` (none of its devices is opened); every
/// mode is allowed, since the source waits for the pipeline as a replay does. Runs until the
/// source finished and the pipeline drained, or `stop`. Throws as run_appliance() does
/// (InputError for a calibration the tracker cannot use, before the source is started).
ApplianceReport run_over_source(const RigCalibration& rig, const std::string& rig_source,
                                SourceModule& source, const BoardConfig& board,
                                const ApplianceOptions& options, const std::atomic<bool>& stop);

}  // namespace wallar::firmware
