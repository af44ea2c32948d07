// SPDX-License-Identifier: Apache-2.0
/// @file stereo_capture.cpp
/// @brief The stereo capture loop; see stereo_capture.hpp.
#include "wallar/drivers/camera/stereo_capture.hpp"

#include <algorithm>
#include <cerrno>

namespace wallar::drivers {

StereoCapture::StereoCapture(V4l2System& sys, const std::array<V4l2CameraConfig, 2>& cameras,
                             source::SensorSink& sink, StereoCaptureConfig config,
                             TriggerOutput* trigger, UsbResetHook reset)
    : sys_(sys), sink_(sink), config_(std::move(config)), trigger_(trigger) {
  for (int i = 0; i < 2; ++i)
    cams_[static_cast<std::size_t>(i)] =
        std::make_unique<V4l2Camera>(sys, cameras[static_cast<std::size_t>(i)], i, reset);
}

StereoCapture::~StereoCapture() {
  if (started_) stop();
}

DurationNs StereoCapture::tolerance_ns() const {
  if (config_.tolerance_ns > 0) return config_.tolerance_ns;
  return std::min(cams_[0]->period_ns(), cams_[1]->period_ns()) / 2;
}

void StereoCapture::start() {
  cams_[0]->start();
  try {
    cams_[1]->start();
  } catch (...) {
    cams_[0]->stop();
    throw;
  }
  pairer_.emplace(tolerance_ns());
  const TimeNs now = sys_.now_ns();
  deadline_ns_ = {now, now};
  if (trigger_ != nullptr) {
    trigger_->set(false);
    next_rise_ns_ = now;
    fall_ns_ = 0;
  }
  started_ = true;
}

void StereoCapture::stop() {
  if (trigger_ != nullptr && fall_ns_ != 0) trigger_->set(false);
  fall_ns_ = 0;
  for (auto& cam : cams_) cam->stop();
  if (pairer_) {
    auto left_over = pairer_->flush();
    for (int i = 0; i < 2; ++i)
      if (left_over[static_cast<std::size_t>(i)])
        sink_.on_unpaired(i, *left_over[static_cast<std::size_t>(i)]);
  }
  started_ = false;
}

bool StereoCapture::both_streaming() const {
  return cams_[0]->state() == CameraState::kStreaming &&
         cams_[1]->state() == CameraState::kStreaming;
}

const sync::PairingStats& StereoCapture::pairing() const {
  return pairer_ ? pairer_->stats() : empty_stats_;
}

TimeNs StereoCapture::service_trigger(TimeNs now_ns) {
  if (trigger_ == nullptr) return now_ns + kNsPerS;
  if (fall_ns_ != 0 && now_ns >= fall_ns_) {
    trigger_->set(false);
    fall_ns_ = 0;
  }
  if (now_ns >= next_rise_ns_) {
    const DurationNs period = std::min(cams_[0]->period_ns(), cams_[1]->period_ns());
    const DurationNs late = now_ns - next_rise_ns_;
    if (late >= period) {  // the thread slept through whole periods: skip, do not burst
      const auto skipped = static_cast<std::uint64_t>(late / period);
      counters_.missed_triggers += skipped;
      next_rise_ns_ += static_cast<DurationNs>(skipped) * period;
    }
    trigger_->set(true);
    ++counters_.triggers;
    fall_ns_ = now_ns + config_.trigger_pulse_ns;
    next_rise_ns_ += period;
  }
  return fall_ns_ != 0 ? std::min(fall_ns_, next_rise_ns_) : next_rise_ns_;
}

void StereoCapture::run_once(DurationNs max_wait_ns) {
  TimeNs now = sys_.now_ns();
  heartbeat_.beat(monotonic_now_ns());  // the supervisor's clock, not the system seam's
  const TimeNs trigger_deadline = service_trigger(now);
  TimeNs wake = std::min({deadline_ns_[0], deadline_ns_[1], trigger_deadline, now + max_wait_ns});
  std::array<pollfd, 2> fds{};
  nfds_t n = 0;
  std::array<int, 2> slot{-1, -1};
  for (int i = 0; i < 2; ++i) {
    const int fd = cams_[static_cast<std::size_t>(i)]->fd();
    if (fd < 0) continue;
    slot[static_cast<std::size_t>(i)] = static_cast<int>(n);
    fds[n].fd = fd;
    fds[n].events = POLLIN;
    ++n;
  }
  const DurationNs wait_ns = std::max<DurationNs>(0, wake - now);
  // Round up so a deadline is never missed by rounding down to 0 ms and spinning.
  const int timeout_ms = static_cast<int>((wait_ns + kNsPerMs - 1) / kNsPerMs);
  const int r = sys_.poll(fds.data(), n, timeout_ms);
  if (r < 0 && errno != EINTR) ++counters_.poll_errors;
  now = sys_.now_ns();
  (void)service_trigger(now);
  for (int i = 0; i < 2; ++i) {
    const int k = slot[static_cast<std::size_t>(i)];
    const short revents = (r > 0 && k >= 0) ? fds[static_cast<std::size_t>(k)].revents : 0;
    deadline_ns_[static_cast<std::size_t>(i)] =
        cams_[static_cast<std::size_t>(i)]->step(now, revents, *this);
  }
}

void StereoCapture::run(TimeNs until_ns, const std::atomic<bool>& stop_flag) {
  while (!stop_flag.load(std::memory_order_acquire) && sys_.now_ns() < until_ns)
    run_once(50 * kNsPerMs);  // bounded so a stop request is seen within 50 ms
  stop();
}

void StereoCapture::on_frame(int cam, CameraFrame&& frame) {
  sync::StereoPairer::Result result = pairer_->push(cam, std::move(frame));
  for (int i = 0; i < 2; ++i)
    if (result.unpaired[static_cast<std::size_t>(i)])
      sink_.on_unpaired(i, *result.unpaired[static_cast<std::size_t>(i)]);
  if (result.pair) sink_.on_stereo(*result.pair);
}

void StereoCapture::on_camera_state(int cam, CameraState state, const char* reason, int err) {
  if (config_.on_state) config_.on_state(cam, state, reason, err);
}

}  // namespace wallar::drivers
