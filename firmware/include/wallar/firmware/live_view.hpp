// SPDX-License-Identifier: Apache-2.0
/// @file live_view.hpp
/// @brief The visualization thread (thesis fig. 3.3): draws the newest frame and pose the
/// tracking thread posts, with the wall model, on the board's display. The tracking thread
/// never waits for it (a newest-only mailbox: frames the renderer could not draw in time are
/// skipped and counted), and it never waits for tracking (it sleeps until a post arrives).
///
/// A lost output (GPU context reset, display unplugged, flip timeout) is reported once (as a
/// log record when given a LogRing, else on stderr) and re-opened every half second until it
/// works; frames posted meanwhile are skipped.
///
/// Latency: each post carries the CLOCK_MONOTONIC time its camera frame was captured (live
/// V4L2: the driver's time stamp; replay: when the replay delivered it); the renderer records
/// present time minus that, the camera-to-display latency.
///
/// Threading: post() from one thread (tracking); the constructor, stop() and the destructor
/// from the owning thread; the display's GL context lives on the internal thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "wallar/core/heartbeat.hpp"
#include "wallar/core/mailbox.hpp"
#include "wallar/core/stereo_frame.hpp"
#include "wallar/core/triple_buffer.hpp"
#include "wallar/dsp/tracking/tracker.hpp"
#include "wallar/firmware/headset_view.hpp"
#include "wallar/firmware/latency_histogram.hpp"
#include "wallar/firmware/log_ring.hpp"
#include "wallar/firmware/rt_thread.hpp"

namespace wallar::firmware {

struct ViewPost {
  StereoFrame frame;
  TimeNs capture_t_ns = 0;
  SE3d T_world_body = SE3d::Identity();
  dsp::TrackingState state = dsp::TrackingState::kInitialising;
  const char* degraded = nullptr;  //!< a static string for the HUD's degraded line, or null
  /// `frame` is the last one before the camera was lost: drawn frozen (dark red, no walls).
  bool camera_lost = false;
};

struct LiveViewStats {
  HeadsetViewStats view;      //!< frames drawn, render times, latencies (every output opened)
  std::uint64_t posted = 0;   //!< frames the tracking side posted
  std::uint64_t skipped = 0;  //!< posted but overwritten before the renderer took them
  std::uint64_t frozen = 0;   //!< posted with the camera lost (drawn frozen when drawn)
  std::uint64_t losses = 0;   //!< times the output failed
  std::uint64_t reopens = 0;  //!< times it was opened again
  std::string display;
};

class LiveView {
 public:
  /// Starts the thread, which opens the display; throws DisplayError (one line) if it cannot.
  /// `walls` is the model drawn, `fps` the HUD's camera rate. With `live_walls` (its one reader
  /// is this view's thread) the newest model published there replaces `walls` as it comes.
  /// `before_draw` (tests: firmware/hil's render-hang fault) runs on the render thread before
  /// each draw, inside the draw's heartbeat.
  LiveView(const RigCalibration& rig, const HeadsetViewOptions& options, WallModel walls,
           double fps, TripleBuffer<WallModel>* live_walls = nullptr,
           ThreadSpec spec = {"render", 0, -1, 0},
           std::function<void(TimeNs now_ns)> before_draw = {}, LogRing* log = nullptr);
  ~LiveView();
  LiveView(const LiveView&) = delete;
  LiveView& operator=(const LiveView&) = delete;

  /// Hands the renderer the newest frame; never blocks, never allocates.
  void post(ViewPost post);
  /// Draws what is pending, stops the thread and returns the statistics (once).
  LiveViewStats stop();
  /// Posts taken and drawn (or failed to draw) so far; any thread.
  [[nodiscard]] std::uint64_t attempts() const { return attempts_.load(std::memory_order_acquire); }
  /// Per drawn frame: render time (from the draw call until present returned) and camera-to-
  /// display latency; frames whose render time exceeded the camera's frame period. Any thread.
  [[nodiscard]] const LatencyHistogram& render_time() const { return render_hist_; }
  [[nodiscard]] const LatencyHistogram& latency() const { return latency_hist_; }
  [[nodiscard]] std::uint64_t misses() const { return misses_.load(std::memory_order_relaxed); }
  /// The output's description (after construction).
  [[nodiscard]] const std::string& display() const { return display_; }
  [[nodiscard]] const RtThread* thread() const { return thread_.get(); }
  /// A job per draw (until present returned; not an output's first draw, whose present sets
  /// the display's mode; the renderer compiled its shaders before), any thread: a draw stuck in a
  /// page flip or a GPU call reads as silent; waiting for frames (the camera lost) does not.
  [[nodiscard]] const Heartbeat& heartbeat() const { return heartbeat_; }

 private:
  void loop(const RigCalibration& rig, const HeadsetViewOptions& options);

  WallModel walls_;
  double fps_;
  TripleBuffer<WallModel>* live_walls_;
  LatencyHistogram render_hist_, latency_hist_;
  std::atomic<std::uint64_t> misses_{0};
  Heartbeat heartbeat_{Heartbeat::Kind::kJob};
  std::function<void(TimeNs)> before_draw_;
  LogRing* log_;  //!< display lost / re-opened; null: stderr
  std::string display_;
  NewestMailbox<ViewPost> mailbox_;
  std::atomic<std::uint32_t> wakeups_{0};
  std::atomic<std::uint64_t> posted_{0};
  std::atomic<std::uint64_t> frozen_{0};
  std::atomic<std::uint64_t> attempts_{0};
  std::atomic<bool> stop_{false};
  std::atomic<int> ready_{0};  // 0 starting, 1 running, -1 failed (error_ set)
  std::string error_;
  LiveViewStats stats_;  // written by the thread, read after join
  std::unique_ptr<RtThread> thread_;
};

}  // namespace wallar::firmware
