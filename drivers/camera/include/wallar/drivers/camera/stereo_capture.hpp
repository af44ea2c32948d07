// SPDX-License-Identifier: Apache-2.0
/// @file stereo_capture.hpp
/// @brief Two V4L2 cameras on one capture thread: poll both, pair their frames by timestamp,
/// hand pairs to a SensorSink, optionally pulse a hardware trigger line.
///
/// One thread polls both cameras' fds with a timeout that is the earliest of: the cameras'
/// own deadlines (stall detection, reopen attempts) and the trigger's next edge. Frames are
/// paired by StereoPairer within a tolerance (default: half the negotiated frame period);
/// frames that find no partner go to SensorSink::on_unpaired() and are counted. While a camera
/// is recovering the other keeps streaming; its frames come out unpaired, and the state change
/// is reported once through `on_state` so the pipeline can say it runs on the IMU alone.
///
/// Trigger: boards whose cameras take an external trigger name a GPIO output; the capture
/// thread asserts it at absolute deadlines t0 + k * period (clock_nanosleep-free: the poll
/// timeout ends at the edge) for `trigger_pulse_ns`. Missed edges (the thread was late by a
/// whole period) are counted, not made up.
///
/// Threading: start/run_once/run/stop on the capture thread; run()'s stop flag may be set from
/// any thread.
/// The sink is called on the capture thread. Nothing allocates after start() (GREY/YUYV).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>

#include "wallar/core/heartbeat.hpp"
#include "wallar/drivers/camera/v4l2_camera.hpp"
#include "wallar/drivers/source/sensor_sink.hpp"
#include "wallar/drivers/sync/stereo_pairer.hpp"

namespace wallar::drivers {

/// A digital output (a GPIO line on a board, a fake in tests).
class TriggerOutput {
 public:
  virtual ~TriggerOutput() = default;
  virtual void set(bool asserted) = 0;
};

struct StereoCaptureConfig {
  DurationNs tolerance_ns = 0;             //!< <= 0: half the negotiated frame period
  DurationNs trigger_pulse_ns = kNsPerMs;  //!< width of the trigger pulse
  /// State changes of either camera (capture thread), e.g. to log them once.
  std::function<void(int cam, CameraState state, const char* reason, int err)> on_state;
};

struct StereoCaptureCounters {
  std::uint64_t triggers = 0;         //!< trigger pulses sent
  std::uint64_t missed_triggers = 0;  //!< edges skipped because the thread was a period late
  std::uint64_t poll_errors = 0;      //!< poll() failures other than EINTR
};

class StereoCapture final : private CameraListener {
 public:
  StereoCapture(V4l2System& sys, const std::array<V4l2CameraConfig, 2>& cameras,
                source::SensorSink& sink, StereoCaptureConfig config = {},
                TriggerOutput* trigger = nullptr, UsbResetHook reset = {});
  ~StereoCapture() override;
  StereoCapture(const StereoCapture&) = delete;
  StereoCapture& operator=(const StereoCapture&) = delete;

  /// Starts both cameras; throws DeviceError (naming the camera and device) if either fails.
  void start();
  /// Stops both cameras; pending frames are flushed to the sink as unpaired.
  void stop();
  /// One iteration: wait (at most max_wait_ns) for a frame or a deadline, step both cameras,
  /// pair, deliver.
  void run_once(DurationNs max_wait_ns);
  /// Runs iterations until `stop_flag` is set or until_ns (CLOCK_MONOTONIC) passes, then stop().
  void run(TimeNs until_ns, const std::atomic<bool>& stop_flag);

  [[nodiscard]] const V4l2Camera& camera(int i) const {
    return *cams_[static_cast<std::size_t>(i)];
  }
  [[nodiscard]] bool both_streaming() const;
  [[nodiscard]] const sync::PairingStats& pairing() const;
  [[nodiscard]] const StereoCaptureCounters& counters() const { return counters_; }
  [[nodiscard]] DurationNs tolerance_ns() const;
  /// Beats at every run_once() (at least every 50 ms from run()), any thread: a capture thread
  /// stuck in a device call reads as silent.
  [[nodiscard]] const Heartbeat& heartbeat() const { return heartbeat_; }

 private:
  void on_frame(int cam, CameraFrame&& frame) override;
  void on_camera_state(int cam, CameraState state, const char* reason, int err) override;
  TimeNs service_trigger(TimeNs now_ns);

  V4l2System& sys_;
  source::SensorSink& sink_;
  StereoCaptureConfig config_;
  TriggerOutput* trigger_;
  std::array<std::unique_ptr<V4l2Camera>, 2> cams_;
  std::array<TimeNs, 2> deadline_ns_{0, 0};
  std::optional<sync::StereoPairer> pairer_;
  sync::PairingStats empty_stats_;
  StereoCaptureCounters counters_;
  Heartbeat heartbeat_{Heartbeat::Kind::kLoop};
  TimeNs next_rise_ns_ = 0;
  TimeNs fall_ns_ = 0;  //!< 0 = line not asserted
  bool started_ = false;
};

}  // namespace wallar::drivers
