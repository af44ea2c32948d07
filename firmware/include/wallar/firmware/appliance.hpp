// SPDX-License-Identifier: Apache-2.0
/// @file appliance.hpp
/// @brief The appliance (thesis fig. 3.3-3.4): the supervisor that builds every module from a
/// board file, couples their channels, runs them on the threads of one table, watches their
/// health and stops them in two phases.
///
/// Modules and channels:
///
///   source (replay | capture + imu) ──ImuSample──▶ SpscRing (never blocks, drops counted)
///        │                          ──StereoFrame─▶ NewestMailbox (counted references; older
///        │                                           frames overwritten and counted) + Wakeup
///        ▼
///   tracking thread: attitude filter (IMU), tracker, degraded modes ──pose──▶ Seqlock
///        │ key-frames ─▶ mapping thread (TrackingAndMapping) ──map──▶ TripleBuffer
///        │ ViewPost ─▶ NewestMailbox ─▶ render thread (LiveView)        │
///        ▼                                                              ▼
///   reconstruction thread (periodic; re-runs when the map grew) ──walls──▶ TripleBuffer ─▶ render
///   supervisor (the calling thread, periodic): stop/exit/reset, SIGUSR1 stats, health,
///   systemd watchdog.
///
/// Deterministic mode (replay only): the source waits until tracking has taken each frame and
/// the IMU ring has room, mapping runs in lock step and reconstruction runs on the tracking
/// thread at fixed points, so poses and walls are bit-identical from run to run for a seed.
///
/// Degraded modes are decided in sensor time on the tracking thread (so they replay the same):
/// no stereo frame for `camera_timeout` of IMU time -> camera lost (IMU-only orientation from
/// the last visual pose, last wall model kept, shown as such); no IMU sample for
/// `imu_timeout` of camera time -> IMU lost (3-D wall search, no gyro prior). Each transition is
/// logged once and counted; both come back without a restart.
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
#include <vector>

#include "wallar/core/pose.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/dsp/walls/room.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/latency_histogram.hpp"
#include "wallar/firmware/live_view.hpp"
#include "wallar/firmware/tracking_and_mapping.hpp"

namespace wallar::firmware {

/// A fault injected into the sensor streams at a time of the (first) replay, in seconds from
/// its first sample: "camera-stall@1.0+0.5", "imu-unplug@0.4+0.6", "corrupt-frame@1.2".
struct FaultSpec {
  enum class Kind : std::uint8_t {
    kCameraStall,
    kImuUnplug,
    kCorruptFrame
  } kind = Kind::kCameraStall;
  double at_s = 0.0;
  double duration_s = 0.0;  //!< stalls and unplugs; corrupt-frame hits one frame
};
/// Parses a fault; throws InputError naming `text` when it is malformed.
FaultSpec parse_fault(const std::string& text);
std::string to_string(const FaultSpec& fault);

struct ApplianceOptions {
  source::ReplayOptions replay;    //!< replay boards: rate, offset, skip
  int loops = 1;                   //!< replay the recording this often (0: until stopped)
  DurationNs max_duration_ns = 0;  //!< > 0: stop after this much wall time
  bool deterministic = false;      //!< see the file comment (replay only)
  bool view = true;                //!< draw the headset view (render thread)
  std::filesystem::path png_dir;   //!< write every `png_every`th drawn view here (empty: none)
  int png_every = 0;
  std::vector<FaultSpec> faults;
  dsp::ScoreMethod wall_method = dsp::ScoreMethod::kBsf;
  double wall_threshold_m = 0.04;  //!< inlier band of the tracker's map
  int max_surfaces = 6;
  DurationNs reconstruct_period_ns = 200 * kNsPerMs;
  double regrow_fraction = 0.10;     //!< re-run when the map grew by this share ...
  std::size_t min_map_points = 60;   //!< ... and has at least this many points
  DurationNs camera_timeout_ns = 0;  //!< 0: max(4 frame periods, 200 ms)
  DurationNs imu_timeout_ns = 100 * kNsPerMs;
  DurationNs supervisor_period_ns = 100 * kNsPerMs;
  DurationNs rss_sample_period_ns = 1 * kNsPerS;  //!< resident memory sampled this often
  bool realtime = true;    //!< SCHED_FIFO, affinity, mlockall where permitted
  std::uint64_t seed = 1;  //!< wall search seeds (seed + run index)
  std::string input_keys;  //!< evdev keyboard ("/dev/input/eventN", "name:..."), or none
  /// One line per event (start, transitions, warnings); default: stderr.
  std::function<void(const std::string&)> log;
};

struct PoseRecord {
  TimeNs t_ns = 0;
  SE3d T_world_body = SE3d::Identity();
  dsp::TrackingState state = dsp::TrackingState::kInitialising;
};

struct ThreadRow {
  std::string name;
  std::string policy;  //!< "FIFO 80" or "OTHER"
  int cpu = -1;
  double cpu_s = 0.0;
  double cpu_percent = 0.0;  //!< of one core over the run
  std::uint64_t wakeups = 0;
  std::uint64_t misses = 0;
  std::optional<std::uint64_t> allocations;  //!< after start-up (when counted in this build)
  std::string note;                          //!< fallback reason or role
};

struct StageRow {
  std::string name;
  LatencySummary latency;
  DurationNs deadline_ns = 0;  //!< 0: none
  std::uint64_t misses = 0;    //!< samples over the deadline
};

struct DegradedCounters {
  std::uint64_t camera_lost = 0, camera_recovered = 0, imu_lost = 0, imu_recovered = 0;
  std::uint64_t imu_only_poses = 0;   //!< poses published from the IMU alone
  std::uint64_t faults_injected = 0;  //!< frames/samples withheld or corrupted
  std::uint64_t resets = 0;
};

struct ApplianceReport {
  std::string source;  //!< what was started
  std::string display;
  source::ReplayStats replay;  //!< summed over loops
  int loops_played = 0;
  std::optional<dsp::RoomResult> room;  //!< the last wall model
  bool room_gravity = false;            //!< found with gravity (2-D mode)
  std::uint64_t reconstructions = 0;
  std::size_t map_points = 0, map_keyframes = 0;
  std::shared_ptr<const dsp::MapSnapshot> map;  //!< the final map (after a global adjustment)
  TrackingCounters tracking;
  DegradedCounters degraded;
  std::vector<PoseRecord> trajectory;  //!< every tracked frame's pose (world = first camera)
  std::uint64_t imu_samples = 0, imu_dropped = 0;
  std::uint64_t frames_in = 0, frames_overwritten = 0, frames_tracked = 0;
  LiveViewStats view;
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
/// board/recording) or DeviceError/DisplayError (a device that cannot be opened) before any
/// thread starts; errors of a module thread are rethrown after the others were stopped.
ApplianceReport run_appliance(const BoardConfig& board, const ApplianceOptions& options,
                              const std::atomic<bool>& stop,
                              std::atomic<bool>* stats_request = nullptr);

/// The stats table (threads, then stages), fixed-width text.
std::string format_stats_table(const std::vector<ThreadRow>& threads,
                               const std::vector<StageRow>& stages);

/// Allocation counting per thread: a build that replaces operator new (the wallar executable,
/// the allocation tests) counts into the calling thread's counter when one is set. The
/// appliance sets one per module thread once its start-up is over.
extern thread_local std::atomic<std::uint64_t>* tl_allocation_counter;
/// True in builds whose operator new counts (set by the replacement's translation unit).
extern bool g_allocations_counted;

}  // namespace wallar::firmware
