// SPDX-License-Identifier: Apache-2.0
/// @file supervisor.cpp
/// @brief run_appliance(): builds the modules and channels from the board, starts their
/// threads from the table, supervises them, stops them in two phases and writes the report.
#include <cstdio>
#include <ctime>
#include <limits>
#include <optional>
#include <stdexcept>

#include "wallar/core/error.hpp"
#include "wallar/core/seqlock.hpp"
#include "wallar/core/triple_buffer.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/firmware/appliance.hpp"
#include "wallar/firmware/appliance/client_server.hpp"
#include "wallar/firmware/appliance/inputs.hpp"
#include "wallar/firmware/appliance/live_module.hpp"
#include "wallar/firmware/appliance/live_publisher.hpp"
#include "wallar/firmware/appliance/pipeline_sink.hpp"
#include "wallar/firmware/appliance/reconstruction.hpp"
#include "wallar/firmware/appliance/recording_tee.hpp"
#include "wallar/firmware/appliance/replay_module.hpp"
#include "wallar/firmware/appliance/snapshots.hpp"
#include "wallar/firmware/appliance/stats.hpp"
#include "wallar/firmware/appliance/thread_table.hpp"
#include "wallar/firmware/appliance/tracking_thread.hpp"
#include "wallar/firmware/board_devices.hpp"
#include "wallar/firmware/offline.hpp"
#include "wallar/firmware/periodic.hpp"
#include "wallar/firmware/rt_thread.hpp"
#include "wallar/firmware/systemd_notify.hpp"
#include "wallar/firmware/wakeup.hpp"
#include "wallar/firmware/world_frames.hpp"

namespace wallar::firmware {
namespace {

void default_log(const std::string& line) { std::fprintf(stderr, "wallar: %s\n", line.c_str()); }

// Waits for the tracking thread's body to return; false once its heartbeat has not moved for
// `hung_ns` meanwhile (a working tracker moves it at every wake-up and every frame done).
bool wait_for_tracking(const RtThread& thread, const TrackingThread& tracker, DurationNs hung_ns) {
  while (!thread.finished()) {
    if (tracker.heartbeat().silent_ns(monotonic_now_ns()) > hung_ns) return false;
    const timespec ts{0, 5 * kNsPerMs};
    nanosleep(&ts, nullptr);
  }
  return true;
}

// A source from outside the board (run_over_source()): its rig and the module.
struct GivenSource {
  const RigCalibration& rig;
  const std::string& rig_source;
  SourceModule& module;  //!< the caller's: it outlives the run
};

ApplianceReport run_modules(const BoardConfig& board, const ApplianceOptions& options_in,
                            const std::atomic<bool>& stop, std::atomic<bool>* stats_request,
                            const recording::EurocRecording* given, GivenSource* given_source);

// Offline, the board sizes the pipeline; none of its devices is opened, inputs included
// (`wallar track --board board/rpi5.yaml` on a laptop has no gpiochip4, nor a remote).
BoardConfig without_devices(const BoardConfig& board) {
  BoardConfig b = board;
  b.reset_button.reset();
  b.exit_button.reset();
  b.keys.clear();
  b.camera_trigger.reset();
  b.live.reset();  // an offline command serves nothing
  b.client.reset();
  if (b.name.empty()) b.name = "offline";
  return b;
}

}  // namespace

const char* to_string(ApplianceMode mode) {
  switch (mode) {
    case ApplianceMode::kRealTime:
      return "real time";
    case ApplianceMode::kEveryFrame:
      return "every frame";
    case ApplianceMode::kLockStep:
      return "lock step";
  }
  return "?";
}

ApplianceReport run_appliance(const BoardConfig& board, const ApplianceOptions& options,
                              const std::atomic<bool>& stop, std::atomic<bool>* stats_request) {
  return run_modules(board, options, stop, stats_request, nullptr, nullptr);
}

ApplianceReport run_over_recording(const recording::EurocRecording& rec, const BoardConfig& board,
                                   const ApplianceOptions& options, const std::atomic<bool>& stop) {
  if (rec.cams[0].frames.empty() || rec.cams[1].frames.empty()) {
    throw InputError(rec.mav0.string() + ": the recording has no stereo frames");
  }
  BoardConfig replay_board = without_devices(board);
  replay_board.source = BoardConfig::Source::kReplay;
  replay_board.replay.recording = rec.mav0;
  return run_modules(replay_board, options, stop, nullptr, &rec, nullptr);
}

ApplianceReport run_over_source(const RigCalibration& rig, const std::string& rig_source,
                                SourceModule& source, const BoardConfig& board,
                                const ApplianceOptions& options, const std::atomic<bool>& stop) {
  GivenSource given{rig, rig_source, source};
  return run_modules(without_devices(board), options, stop, nullptr, nullptr, &given);
}

namespace {

ApplianceReport run_modules(const BoardConfig& board_in, const ApplianceOptions& options_in,
                            const std::atomic<bool>& stop, std::atomic<bool>* stats_request,
                            const recording::EurocRecording* given, GivenSource* given_source) {
  // A live board's devices become what was found at start (GPIO chips by path).
  BoardConfig board = board_in;
  ApplianceOptions options = options_in;
  if (!options.log) options.log = default_log;
  const bool replay = given_source == nullptr && board.source == BoardConfig::Source::kReplay;
  const bool lockstep = options.mode == ApplianceMode::kLockStep;
  const bool every_frame = options.mode != ApplianceMode::kRealTime;
  // A given source waits for the pipeline as a replay does; a replay plan needs a recording.
  if ((!replay && options.replay_plan) || (!replay && given_source == nullptr && every_frame)) {
    throw InputError(board.file.string() +
                     ": --deterministic, --fault and --loop need a replay board");
  }
  ApplianceReport report;
  report.mode = options.mode;
  const TimeNs t_start = monotonic_now_ns();

  // Everything that can fail on bad input or a missing device, before any thread starts.
  std::optional<recording::EurocRecording> read;
  const recording::EurocRecording* rec = given;
  RigCalibration rig;
  std::string rig_source;
  if (given_source != nullptr) {
    rig = given_source->rig;
    rig_source = given_source->rig_source;
  } else if (replay) {
    if (rec == nullptr) rec = &read.emplace(recording::read_recording(board.replay.recording));
    rig = rec->rig();
    rig_source = rec->mav0.string();
  } else {
    if (!board.calibration) {
      throw InputError(board.file.string() +
                       ": a live board needs calibration: (the rig's "
                       "intrinsics and extrinsics) to track");
    }
    rig = recording::read_rig_calibration(*board.calibration);
    rig_source = board.calibration->string();
    // The board against its calibration (camera modes, the camera-IMU transform), then every
    // device by its stable name (GPIO chips by label, udev links), before anything opens:
    // each failure one line naming the board file's key.
    BoardCheck check;
    check_rig(board_in, rig, rig_source, &check);
    board = resolve_board_devices(board_in, drivers::DeviceTree(), &check);
    throw_if_failed(board_in, check, options.log);
  }
  // Fixed priorities pace real time; a fast replay runs every thread as SCHED_OTHER.
  const bool realtime = options.realtime && !(replay && options.replay.rate <= 0.0);
  if (realtime) {
    const MemoryLock lock = lock_memory();
    report.memory_locked = lock.locked;
    if (!lock.locked) options.log(lock.warning);
  }
  Inputs inputs(board, options.input_keys);
  SystemdNotifier notifier;

  // Channels.
  std::atomic<bool> stop_modules{false};
  Wakeup tracking_wakeup;
  PipelineSink pipeline(tracking_wakeup, stop_modules, every_frame);
  Seqlock<PoseSnapshot> pose;
  TripleBuffer<WallModel> walls_channel;
  TripleBuffer<MapPtr> map_channel;
  // The live server's own (each triple buffer has one reader).
  TripleBuffer<WallModel> live_walls_channel;
  TripleBuffer<MapPtr> live_map_channel;
  TripleBuffer<WallModel> client_walls_channel;  // the client API's

  // The live server listens before any thread starts (a port in use is an InputError here),
  // and outlives the log thread, which copies each line to it.
  std::unique_ptr<LivePublisher> live;
  if (board.live) {
    live = std::make_unique<LivePublisher>(*board.live, rig, LivePublisherOptions{}, pose,
                                           live_map_channel, live_walls_channel);
    report.live_url = live->url();
  }
  std::function<void(const std::string&)> log_out = options.log;
  if (live) {
    log_out = [&live, log = options.log](const std::string& line) {
      log(line);
      live->log(line);
    };
  }

  // The log: fixed-rate threads post records, a SCHED_OTHER thread formats and writes them
  // (no stdio or formatting on a SCHED_FIFO thread), rate-limited for the journal.
  LogRing log_ring;
  LogThread log_thread(log_ring, log_out, thread_spec("log", realtime, &board), {});

  // Modules.
  TrackingThreadOptions tracking;
  tracking.tracking = tracking_options(board.tracking);
  if (options.adjust_tracking) options.adjust_tracking(tracking.tracking);
  if (lockstep) tracking.tracking.mapping_thread = false;
  tracking.tracking.use_gyro = options.use_gyro;
  tracking.tracking.mapping_thread_spec = thread_spec("mapping", realtime, &board);
  tracking.tracking.map_channel = &map_channel;
  if (live) tracking.tracking.live_map_channel = &live_map_channel;
  tracking.every_frame = every_frame;
  tracking.camera_timeout_ns = options.camera_timeout_ns;
  tracking.imu_timeout_ns = options.imu_timeout_ns;
  tracking.max_records = options.max_records;
  tracking.log = &log_ring;
  tracking.before_frame = options.before_frame;
  tracking.on_frame_pose = options.on_frame_pose;
  ReconstructionOptions reconstruction_options;
  reconstruction_options.method = options.wall_method;
  reconstruction_options.threshold_m = options.wall_threshold_m;
  reconstruction_options.max_surfaces = options.max_surfaces;
  reconstruction_options.regrow_fraction = options.regrow_fraction;
  reconstruction_options.min_map_points = options.min_map_points;
  reconstruction_options.seed = options.seed;
  reconstruction_options.period_ns = options.reconstruct_period_ns;
  Reconstruction reconstruction(reconstruction_options,
                                static_cast<std::size_t>(board.tracking.max_map_points),
                                walls_channel);
  if (live) reconstruction.also_publish_to(&live_walls_channel);
  if (board.client) reconstruction.also_publish_to(&client_walls_channel);
  std::unique_ptr<TrackingThread> tracker;
  try {
    tracker = std::make_unique<TrackingThread>(rig, tracking, pipeline, tracking_wakeup, pose,
                                               nullptr, lockstep ? &reconstruction : nullptr);
  } catch (const std::invalid_argument& e) {
    throw InputError(rig_source + ": calibration: " + e.what());
  }
  report.T_body_rect = tracker->system().tracker().T_body_rect();
  // The client API's socket, before any thread starts (a path in use is an InputError here).
  // Its world is the first body pose's, as the run's files.
  std::unique_ptr<ClientServer> client;
  if (board.client) {
    // The view apps render from is the rectified left camera, the headset view's.
    client = std::make_unique<ClientServer>(*board.client, report.T_body_rect, report.T_body_rect,
                                            pose, client_walls_channel);
    report.client_socket = client->path();
    tracker->set_client_pose(&client->publisher(), replay);
  }
  if (live) tracker->set_live(live.get());
  std::unique_ptr<LiveView> view;
  if (options.view) {
    HeadsetViewOptions vo = view_options(board.display);
    vo.png_dir = options.png_dir;
    vo.png_every = options.png_dir.empty() ? 0 : std::max(1, options.png_every);
    // Given walls are in the first body pose's world; the view draws in the tracker's.
    WallModel walls = options.view_walls
                          ? transformed(*options.view_walls, report.T_body_rect.inverse())
                          : WallModel{};
    view = std::make_unique<LiveView>(rig, vo, std::move(walls), rig.cams[0].rate_hz,
                                      options.view_walls ? nullptr : &walls_channel,
                                      thread_spec("render", realtime, &board), options.before_draw,
                                      &log_ring);
    report.display = view->display();
    tracker->set_view(view.get());
  }
  // `wallar run --record`: the samples go to the recorder too (never waiting for it). Before
  // the source, so that it outlives the source's threads.
  std::optional<RecordingTee> tee;
  if (options.record != nullptr) tee.emplace(pipeline, *options.record);
  std::unique_ptr<SourceModule> owned_source;
  SourceModule* source = nullptr;
  ReplayModule* replay_module = nullptr;
  if (given_source != nullptr) {
    source = &given_source->module;
  } else if (replay) {
    auto r = std::make_unique<ReplayModule>(
        *rec, options.replay, options.replay_plan ? options.replay_plan(*rec) : nullptr, &board);
    replay_module = r.get();
    owned_source = std::move(r);
    source = owned_source.get();
  } else {
    owned_source = std::make_unique<LiveModule>(board, &log_ring);
    source = owned_source.get();
  }

  // Threads, consumers first so nothing produced is lost.
  std::atomic<std::uint64_t> tracking_allocs{0}, supervisor_allocs{0};
  RtThread tracking_thread(thread_spec("tracking", realtime, &board),
                           [&] { tracker->run(stop_modules, &tracking_allocs); });
  std::unique_ptr<ReconstructionThread> reconstruct_thread;
  if (!lockstep) {
    reconstruct_thread = std::make_unique<ReconstructionThread>(
        reconstruction, map_channel, pose, options.reconstruct_period_ns,
        thread_spec("reconstruct", realtime, &board), stop_modules);
  }
  source::SensorSink& sink = tee ? static_cast<source::SensorSink&>(*tee) : pipeline;
  drivers::ImuSampleSink& imu_sink = tee ? static_cast<drivers::ImuSampleSink&>(*tee) : pipeline;
  try {
    source->start(sink, imu_sink, realtime, stop_modules);  // live: opens the devices
  } catch (...) {
    // The consumers already run: stop them before unwinding joins them.
    stop_modules.store(true, std::memory_order_release);
    tracking_wakeup.notify();
    throw;
  }
  report.source = source->describe();
  {
    char line[700];
    std::snprintf(line, sizeof line, "board %s: %s; display %s; inputs %s%s%s", board.name.c_str(),
                  report.source.c_str(), view ? report.display.c_str() : "none",
                  inputs.describe().c_str(), options.mode == ApplianceMode::kRealTime ? "" : "; ",
                  options.mode == ApplianceMode::kRealTime ? "" : to_string(options.mode));
    options.log(line);
  }
  {
    // Placement fallbacks (no SCHED_FIFO, a missing CPU), said once per thread at start.
    std::vector<const RtThread*> started = source->threads();
    started.push_back(&tracking_thread);
    if (reconstruct_thread) started.push_back(&reconstruct_thread->thread());
    started.push_back(tracker->system().mapping_thread());
    if (view) started.push_back(view->thread());
    for (const RtThread* t : started) {
      if (t != nullptr && !t->placement().fallback.empty()) {
        options.log("thread " + t->spec().name + ": " + t->placement().fallback);
      }
    }
  }
  // The supervisor's loop runs above the worker threads (thread table): on a board whose
  // replay and tracking threads kept both CPUs busy (the emulator: PNG decoding and tracking
  // at SCHED_FIFO), a SCHED_OTHER supervisor went seconds without running and missed its
  // watchdog keep-alives while healthy. A wake-up costs microseconds; after the loop (the
  // final adjustment, the report) the main thread is SCHED_OTHER again.
  std::optional<ScopedThreadPriority> supervisor_priority;
  if (realtime) {
    const ThreadTableEntry entry = thread_table_entry("supervisor", &board);
    supervisor_priority.emplace(entry.priority, entry.round_robin);
    if (!supervisor_priority->placement().fallback.empty())
      options.log("thread supervisor: " + supervisor_priority->placement().fallback);
  }
  notifier.ready();
  notifier.status("running");

  // Supervisor.
  // The mapping thread lives from start to finish (a reset does not replace it).
  auto live_rows = [&](DurationNs run_ns) {
    std::vector<ThreadRow> threads;
    for (const RtThread* t : source->threads()) {
      if (t != nullptr) threads.push_back(row_of(*t, run_ns, 0, 0, source->allocations_of(t)));
    }
    threads.push_back(
        row_of(tracking_thread, run_ns, tracker->wakeups(), tracker->misses(), &tracking_allocs));
    if (const RtThread* m = tracker->system().mapping_thread()) {
      threads.push_back(row_of(*m, run_ns, 0, 0, nullptr));
    }
    if (reconstruct_thread) {
      threads.push_back(row_of(reconstruct_thread->thread(), run_ns, reconstruct_thread->wakeups(),
                               reconstruct_thread->misses(), &reconstruct_thread->allocations()));
    }
    if (view) {
      if (const RtThread* r = view->thread()) {
        threads.push_back(row_of(*r, run_ns, view->attempts(), view->misses(), nullptr));
      }
    }
    threads.push_back(row_of(log_thread.thread(), run_ns, 0, 0, nullptr));
    if (live && live->thread() != nullptr) {
      threads.push_back(row_of(*live->thread(), run_ns, 0, 0, nullptr));
    }
    if (client && client->thread() != nullptr) {
      threads.push_back(row_of(*client->thread(), run_ns, client->wakeups(), 0, nullptr));
      const ClientServerCounters c = client->counters();
      threads.back().note = "clients " + std::to_string(c.clients) + ", accepted " +
                            std::to_string(c.accepted) + ", dropped " + std::to_string(c.dropped) +
                            ", malformed " + std::to_string(c.malformed) + ", refused " +
                            std::to_string(c.refused);
    }
    return threads;
  };
  const DurationNs frame_period = tracker->frame_period_ns();
  auto stage_rows = [&] {
    std::vector<StageRow> stages;
    stages.push_back(stage_row("imu -> filter", tracker->imu_latency(), 0, 0));
    stages.push_back(stage_row("capture -> tracking", tracker->queue_latency(), 0, 0));
    stages.push_back(stage_row("tracking", tracker->track_time(), frame_period, tracker->misses()));
    stages.push_back(stage_row("reconstruction", reconstruction.time(), 0, 0));
    if (view) {
      stages.push_back(stage_row("render", view->render_time(), frame_period, view->misses()));
      stages.push_back(stage_row("camera -> display", view->latency(), 0, 0));
    }
    return stages;
  };

  // Health: the watchdog is fed only while every fixed-rate thread and the display make
  // progress. A render stuck in a page flip, a capture or imu thread stuck in a device call or
  // a wall search that never returns withholds it as a hung tracker does, and the service
  // manager restarts the appliance (WatchdogSec). Loops wake every 10-100 ms; a draw takes
  // tens of ms; a wall search a few hundred.
  struct Watched {
    const char* name;
    const Heartbeat* heartbeat;
    DurationNs limit_ns;
    bool stalled = false;
  };
  std::vector<Watched> watched;
  watched.push_back({"tracking", &tracker->heartbeat(), 2 * kNsPerS});
  for (const auto& [name, heartbeat] : source->heartbeats()) {
    watched.push_back({name, heartbeat, 2 * kNsPerS});
  }
  if (reconstruct_thread) {
    watched.push_back({"reconstruct", &reconstruct_thread->heartbeat(), 10 * kNsPerS});
  }
  if (view) watched.push_back({"render", &view->heartbeat(), 2 * kNsPerS});

  // SIGUSR1's stats table: formatted and written by the log thread (SCHED_OTHER), never on
  // this SCHED_FIFO loop; withdrawn before the modules it reads are torn down.
  log_thread.set_report(
      stats_request,
      [&] { return format_stats_table(live_rows(monotonic_now_ns() - t_start), stage_rows()); },
      [](const std::string& table) { std::fprintf(stderr, "%s", table.c_str()); });
  struct WithdrawReport {  // also when an exception leaves this scope
    LogThread& log;
    ~WithdrawReport() { log.set_report(nullptr, {}, {}); }
  } withdraw_report{log_thread};

  // The live server's thread reads the same rows; stopped before the modules go (also when an
  // exception leaves this scope).
  if (live) {
    live->start(thread_spec("live", realtime, &board),
                [&](std::vector<ThreadRow>& threads, std::vector<StageRow>& stages) {
                  threads = live_rows(monotonic_now_ns() - t_start);
                  stages = stage_rows();
                });
    log_out(live->describe());
  }
  // The client API's thread: stopped after the last wall search (below), so apps get the
  // final model; also when an exception leaves this scope.
  if (client) {
    client->start(thread_spec("client", realtime, &board));
    log_out(client->describe());
  }
  struct StopClient {
    ClientServer* client;
    ~StopClient() {
      if (client != nullptr) client->stop(0);
    }
  } stop_client{client.get()};
  struct StopLive {
    LivePublisher* live;
    ~StopLive() {
      if (live != nullptr) live->stop();
    }
  } stop_live{live.get()};

  report.rss_kb.reserve(1 << 16);
  TimeNs next_rss_ns = t_start;
  PeriodicTimer supervisor(options.supervisor_period_ns);
  std::uint64_t supervisor_wakeups = 0;
  std::string tracking_error;
  std::exception_ptr source_error;
  tl_allocation_counter = &supervisor_allocs;
  for (;;) {
    supervisor.wait();
    ++supervisor_wakeups;
    const TimeNs now = monotonic_now_ns();
    if (now >= next_rss_ns && report.rss_kb.size() < report.rss_kb.capacity()) {
      report.rss_kb.push_back(current_rss_kb());
      next_rss_ns = now + options.rss_sample_period_ns;
    }
    if (stop.load(std::memory_order_acquire)) {
      report.stop_reason = "signal";
      report.interrupted = true;
      break;
    }
    if (options.max_duration_ns > 0 && now - t_start >= options.max_duration_ns) {
      report.stop_reason = "time limit";
      break;
    }
    if (tracking_thread.failed()) {
      tracking_error = "tracking: " + tracking_thread.error();
      break;
    }
    if (std::exception_ptr e = source->error()) {
      source_error = e;
      break;
    }
    if (source->finished() && pipeline.drained()) {
      report.stop_reason = replay ? "end of replay" : "sensors stopped";
      break;
    }
    drivers::InputAction action = inputs.poll(now);
    if (action == drivers::InputAction::kNone && options.test_input)
      action = options.test_input(now);
    switch (action) {
      case drivers::InputAction::kExit:
        report.stop_reason = "exit input";
        report.interrupted = true;
        break;
      case drivers::InputAction::kReset:
        tracker->request_reset();
        [[fallthrough]];
      case drivers::InputAction::kNone:
        break;
    }
    if (report.interrupted) break;
    bool any_stalled = false;
    for (Watched& w : watched) {
      const bool stalled = w.heartbeat->silent_ns(now) > w.limit_ns;
      if (stalled != w.stalled) {
        w.stalled = stalled;
        if (stalled) {
          log_ring.post("%s thread stalled (no progress for %g s): watchdog withheld",
                        {w.name, ns_to_s(w.limit_ns)});
        } else {
          log_ring.post("%s thread alive again", {w.name});
        }
      }
      any_stalled = any_stalled || stalled;
    }
    if (!any_stalled && notifier.watchdog_due(now)) notifier.watchdog(now);
  }
  tl_allocation_counter = nullptr;
  log_thread.set_report(nullptr, {}, {});
  if (live) {
    live->stop();
    report.live = live->counters();
    if (!live->error().empty()) options.log("live server stopped early: " + live->error());
  }
  const bool supervisor_fifo = supervisor_priority && supervisor_priority->placement().fifo;
  supervisor_priority.reset();
  notifier.stopping();

  // Phase one: break the links. Producers stop producing, waits are released.
  stop_modules.store(true, std::memory_order_release);
  tracking_wakeup.notify();
  pipeline.release_producers();
  // Phase two: join and destroy, source first (it may be inside a device call).
  if (!source->join_within(3 * kNsPerS)) {
    log_thread.stop();  // what the threads posted first
    options.log("the source did not stop within 3 s (stuck in a device call): exiting without it");
    std::fflush(nullptr);
    std::_Exit(1);
  }
  // A source that failed while the supervisor saw it finish: its error still counts.
  if (!source_error) source_error = source->error();
  report.devices = source->device_counters();
  // A hung tracking thread is not waited for: 4 s without a heartbeat (the health check's 2 s
  // and as long again) ends the process without it, as with a stuck source. Before, a stop
  // of a hung appliance waited for the service manager's SIGKILL (20 s under systemd), also
  // when the hang began just before the stop and the health check had not seen it yet.
  if (!wait_for_tracking(tracking_thread, *tracker, 4 * kNsPerS)) {
    log_thread.stop();
    options.log(
        "the tracking thread is hung (no heartbeat for 4 s) and did not stop: exiting without "
        "its outputs");
    std::fflush(nullptr);
    std::_Exit(1);
  }
  tracking_thread.join();
  if (reconstruct_thread) reconstruct_thread->join();
  const DurationNs run_ns = monotonic_now_ns() - t_start;
  report.threads = live_rows(run_ns);
  ThreadRow sup;
  sup.name = "supervisor";
  sup.policy = supervisor_fifo
                   ? "FIFO " + std::to_string(thread_table_entry("supervisor", &board).priority)
                   : std::string("OTHER");
  sup.wakeups = supervisor_wakeups;
  sup.misses = supervisor.misses();
  if (g_allocations_counted) sup.allocations = supervisor_allocs.load();
  sup.note = thread_table_entry("supervisor", &board).role;
  report.threads.push_back(sup);
  // The final map (mapping stopped after a global adjustment) and its walls.
  const MapPtr final_map = tracker->finish();
  if (final_map) {
    report.map = final_map;
    report.map_points = final_map->points.size();
    report.map_keyframes = final_map->keyframe_centres.size();
    const PoseSnapshot p = pose.load();
    reconstruction.maybe_run(*final_map, down_of(p), p.epoch, true);
  }
  if (view) report.view = view->stop();
  if (client) {
    client->stop();  // the final model goes out first (a short flush)
    report.client = client->counter_list();
    if (!client->error().empty()) options.log("client API stopped early: " + client->error());
  }
  log_thread.stop();  // every thread that posts has stopped: the last lines are out
  report.stages = stage_rows();
  report.mapping_times_ns = tracker->system().mapping_times_ns();
  LatencyHistogram mapping;
  for (const std::int64_t ns : report.mapping_times_ns) mapping.record(ns);
  report.stages.insert(report.stages.begin() + 3, stage_row("mapping (local BA)", mapping, 0, 0));
  if (source_error) std::rethrow_exception(source_error);  // e.g. the replay's InputError
  if (!tracking_error.empty()) throw std::runtime_error(tracking_error);

  report.room = reconstruction.result();
  report.room_gravity = reconstruction.gravity();
  report.reconstructions = reconstruction.runs();
  report.tracking = tracker->system().counters();
  report.degraded = tracker->degraded();
  report.trajectory = tracker->records();
  report.events = tracker->events();
  report.imu = tracker->imu_seen();
  report.imu_samples = pipeline.imu_in();
  report.imu_dropped = pipeline.imu_dropped();
  report.frames_in = pipeline.frames_in();
  report.frames_overwritten = pipeline.frames_overwritten();
  report.frames_tracked = tracker->tracked();
  if (replay_module != nullptr) {
    report.replay = replay_module->stats();
    report.loops_played = replay_module->loops_played();
    report.degraded.faults_injected = replay_module->injected();
  }
  report.wall_time_ns = run_ns;
  report.max_rss_kb = max_rss_kb();
  return report;
}

}  // namespace
}  // namespace wallar::firmware
