// SPDX-License-Identifier: Apache-2.0
/// @file live_view.cpp
/// @brief The visualization thread: mailbox -> HeadsetView.
#include "wallar/firmware/live_view.hpp"

#include <chrono>
#include <cstdio>
#include <thread>

namespace wallar::firmware {

LiveView::LiveView(const RigCalibration& rig, const HeadsetViewOptions& options, WallModel walls,
                   double fps, TripleBuffer<WallModel>* live_walls, ThreadSpec spec,
                   std::function<void(TimeNs)> before_draw, LogRing* log)
    : walls_(std::move(walls)),
      fps_(fps),
      live_walls_(live_walls),
      before_draw_(std::move(before_draw)),
      log_(log) {
  thread_ =
      std::make_unique<RtThread>(std::move(spec), [this, rig, options] { loop(rig, options); });
  // The display opens on the thread that will draw; wait for it to say how that went.
  int state = 0;
  while ((state = ready_.load(std::memory_order_acquire)) == 0) {
    ready_.wait(0, std::memory_order_acquire);
  }
  if (state < 0) {
    thread_->join();
    throw display::DisplayError(error_);
  }
}

LiveView::~LiveView() {
  if (thread_->joinable()) stop();
}

void LiveView::post(ViewPost post) {
  if (post.camera_lost) frozen_.fetch_add(1, std::memory_order_relaxed);
  mailbox_.post(std::move(post));
  posted_.fetch_add(1, std::memory_order_relaxed);
  wakeups_.fetch_add(1, std::memory_order_release);
  wakeups_.notify_one();  // a futex wake: never blocks
}

LiveViewStats LiveView::stop() {
  stop_.store(true, std::memory_order_release);
  wakeups_.fetch_add(1, std::memory_order_release);
  wakeups_.notify_one();
  if (thread_->joinable()) thread_->join();
  stats_.posted = posted_.load(std::memory_order_relaxed);
  stats_.skipped = mailbox_.overwritten();
  stats_.frozen = frozen_.load(std::memory_order_relaxed);
  return stats_;
}

namespace {

constexpr auto kReopenPeriod = std::chrono::milliseconds(500);

void accumulate(HeadsetViewStats& into, const HeadsetViewStats& from) {
  into.frames += from.frames;
  into.written += from.written;
  into.present_failures += from.present_failures;
  into.on_screen += from.on_screen;
  if (from.last_t_ns >= 0) into.last_t_ns = from.last_t_ns;
  into.render_ns.insert(into.render_ns.end(), from.render_ns.begin(), from.render_ns.end());
  into.latency_ns.insert(into.latency_ns.end(), from.latency_ns.begin(), from.latency_ns.end());
  into.written_files.insert(into.written_files.end(), from.written_files.begin(),
                            from.written_files.end());
}

}  // namespace

void LiveView::loop(const RigCalibration& rig, const HeadsetViewOptions& options) {
  std::unique_ptr<HeadsetView> view;
  try {
    view = std::make_unique<HeadsetView>(rig, options);
  } catch (const std::exception& e) {
    error_ = e.what();
    ready_.store(-1, std::memory_order_release);
    ready_.notify_one();
    return;
  }
  stats_.display = view->describe();
  display_ = stats_.display;
  ready_.store(1, std::memory_order_release);
  ready_.notify_one();
  ViewPost post;
  display::HudState hud;
  hud.fps = fps_;
  hud.walls = static_cast<int>(walls_.walls.size());
  for (;;) {
    if (view == nullptr) {
      // Lost: try again every kReopenPeriod; tracking goes on posting (skipped frames).
      for (auto slept = std::chrono::milliseconds(0);
           slept < kReopenPeriod && !stop_.load(std::memory_order_acquire);
           slept += std::chrono::milliseconds(50)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
      if (stop_.load(std::memory_order_acquire)) break;
      try {
        view = std::make_unique<HeadsetView>(rig, options);
        ++stats_.reopens;
        if (log_ != nullptr) {
          log_->post("display: re-opened %s", {LogArg::copied()}, view->describe().c_str());
        } else {
          std::fprintf(stderr, "wallar: display: re-opened %s\n", view->describe().c_str());
        }
      } catch (const std::exception&) {
        // Still gone; said once when it was lost.
      }
      continue;
    }
    const std::uint32_t seen = wakeups_.load(std::memory_order_acquire);
    if (mailbox_.take(post)) {
      const WallModel* walls = &walls_;
      if (live_walls_ != nullptr) {
        live_walls_->refresh();
        if (live_walls_->published() > 0) walls = &live_walls_->front();
      }
      hud.tracking = dsp::to_string(post.state);
      hud.walls = static_cast<int>(walls->walls.size());
      hud.degraded = post.degraded != nullptr ? post.degraded : "";
      hud.image_frozen = post.camera_lost;
      const bool valid = post.state == dsp::TrackingState::kTracking && !post.camera_lost;
      // Every draw but an output's first (its first present sets the display's mode; the
      // shaders were compiled by the renderer's warm-up draw) is a job the supervisor watches.
      if (view->stats().frames > 0) heartbeat_.begin(monotonic_now_ns());
      if (before_draw_) before_draw_(monotonic_now_ns());
      const TimeNs t0 = monotonic_now_ns();
      const bool shown =
          view->show(post.frame, post.capture_t_ns, post.T_world_body, valid, walls, hud);
      const TimeNs t1 = monotonic_now_ns();
      heartbeat_.end(t1);
      if (shown) {
        render_hist_.record(t1 - t0);
        if (post.capture_t_ns > 0) latency_hist_.record(t1 - post.capture_t_ns);
        if (fps_ > 0.0 && static_cast<double>(t1 - t0) > 1e9 / fps_) {
          misses_.fetch_add(1, std::memory_order_relaxed);
        }
      }
      post = ViewPost{};  // release the frame's buffers now
      if (!shown) {
        ++stats_.losses;
        const auto period_ms = static_cast<long long>(kReopenPeriod.count());
        if (log_ != nullptr) {
          log_->post("display lost: %s; re-opening every %lld ms", {LogArg::copied(), period_ms},
                     view->last_error().c_str());
        } else {
          std::fprintf(stderr, "wallar: display lost: %s; re-opening every %lld ms\n",
                       view->last_error().c_str(), period_ms);
        }
        accumulate(stats_.view, view->stats());
        view.reset();
      }
      attempts_.fetch_add(1, std::memory_order_release);
      continue;
    }
    if (stop_.load(std::memory_order_acquire)) break;
    wakeups_.wait(seen, std::memory_order_acquire);
  }
  if (view != nullptr) accumulate(stats_.view, view->stats());
}

}  // namespace wallar::firmware
