// SPDX-License-Identifier: Apache-2.0
/// @file live_stereo.cpp
/// @brief Opening the board's cameras and the capture thread's loop.
#include "wallar/firmware/live_stereo.hpp"

#include <cstdio>
#include <cstring>

#include "wallar/core/error.hpp"
#include "wallar/drivers/bus/gpio.hpp"
#include "wallar/drivers/camera/uvc_reset.hpp"

namespace wallar::firmware {
namespace {

// The board's trigger line as the capture's trigger output.
class GpioTrigger final : public drivers::TriggerOutput {
 public:
  explicit GpioTrigger(const GpioLine& line)
      : out_(drivers::GpioLineSpec{line.chip, static_cast<unsigned>(line.line), line.active_low},
             "wallar-camera-trigger") {}
  void set(bool asserted) override { out_.set(asserted); }

 private:
  drivers::GpioOutput out_;
};

}  // namespace

std::array<drivers::V4l2CameraConfig, 2> camera_configs(const BoardConfig& board) {
  std::array<drivers::V4l2CameraConfig, 2> out;
  for (int i = 0; i < 2; ++i) {
    const CameraConfig& c = board.cameras[i];
    drivers::V4l2CameraConfig& k = out[static_cast<std::size_t>(i)];
    k.name = i == 0 ? "left" : "right";
    if (c.device.empty())
      throw_input_error(board.file.string(), 0,
                        std::string("cameras.") + k.name + ".device is required for live capture");
    k.device = c.device;
    k.usb_id = c.usb_id;
    k.width_px = c.width_px;
    k.height_px = c.height_px;
    k.fps = c.fps;
    const auto format = drivers::parse_camera_pixel_format(c.pixel_format);
    if (!format)
      throw_input_error(board.file.string(), 0,
                        "cameras." + k.name + ".format: unknown '" + c.pixel_format + "'");
    k.format = *format;
  }
  return out;
}

std::string camera_pair_name(const BoardConfig& board) {
  return "left " + board.cameras[0].device + ", right " + board.cameras[1].device;
}

struct LiveStereo::Parts {
  // Not owned: a frame a consumer still holds after the capture is gone unmaps through it.
  drivers::V4l2System* sys = nullptr;
  std::unique_ptr<GpioTrigger> trigger;
  std::unique_ptr<drivers::StereoCapture> capture;
  std::array<std::string, 2> names;
  std::string pair;  // "left DEVICE, right DEVICE"
  std::optional<sync::SyncAssessment> sync;
  Log log;
  LogRing* ring = nullptr;
};

LiveStereo::LiveStereo(const BoardConfig& board, source::SensorSink& sink, Log log,
                       drivers::V4l2System& sys, LogRing* ring)
    : parts_(std::make_unique<Parts>()) {
  parts_->ring = ring;
  parts_->sys = &sys;
  const auto configs = camera_configs(board);
  parts_->names = {configs[0].name + " camera (" + configs[0].device + ")",
                   configs[1].name + " camera (" + configs[1].device + ")"};
  parts_->pair = camera_pair_name(board);
  parts_->log = log ? std::move(log)
                    : [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
  if (board.camera_trigger) parts_->trigger = std::make_unique<GpioTrigger>(*board.camera_trigger);
  drivers::StereoCaptureConfig sc;
  if (board.sync_tolerance_ms > 0.0)
    sc.tolerance_ns = static_cast<DurationNs>(board.sync_tolerance_ms * 1e6);
  Parts* parts = parts_.get();
  sc.on_state = [parts](int cam, drivers::CameraState state, const char* reason, int err) {
    const bool pairs = parts->capture != nullptr && parts->capture->both_streaming();
    if (parts->ring != nullptr) {
      // The capture thread runs SCHED_FIFO: a record, formatted by the log thread.
      parts->ring->post(
          "%s: %s (%s%s%s); %s",
          {LogArg::copied(), drivers::to_string(state), reason != nullptr ? reason : "",
           err != 0 ? ": " : "", err != 0 ? LogArg::error(err) : LogArg(""),
           pairs ? "stereo pairs again" : "no stereo pairs meanwhile, the IMU stream goes on"},
          parts->names[static_cast<std::size_t>(cam)].c_str());
      return;
    }
    std::string line = "wallar: " + parts->names[static_cast<std::size_t>(cam)] + ": " +
                       drivers::to_string(state) + " (" + reason;
    if (err != 0) line += std::string(": ") + std::strerror(err);
    line += ")";
    const bool both = parts->capture != nullptr && parts->capture->both_streaming();
    line += both ? "; stereo pairs again" : "; no stereo pairs meanwhile, the IMU stream goes on";
    parts->log(line);
  };
  parts_->capture = std::make_unique<drivers::StereoCapture>(
      *parts_->sys, configs, sink, std::move(sc), parts_->trigger.get(), drivers::reset_uvc_camera);
  parts_->capture->start();
}

LiveStereo::~LiveStereo() = default;

const drivers::StereoCapture& LiveStereo::capture() const { return *parts_->capture; }

const std::optional<sync::SyncAssessment>& LiveStereo::sync_assessment() const {
  return parts_->sync;
}

std::string LiveStereo::description() const {
  std::string out;
  for (int i = 0; i < 2; ++i) {
    const drivers::V4l2Camera& cam = parts_->capture->camera(i);
    const drivers::V4l2Negotiated& n = cam.negotiated();
    char buf[256];
    std::snprintf(buf, sizeof buf, "%s%s %s %dx%d %s %.1f Hz (%s)", i == 0 ? "" : "; ",
                  cam.config().name.c_str(), cam.config().device.c_str(), n.width_px, n.height_px,
                  drivers::fourcc_to_string(n.fourcc).c_str(), n.fps, n.driver.c_str());
    out += buf;
  }
  return out;
}

void LiveStereo::run(TimeNs until_ns, const std::atomic<bool>& stop) {
  drivers::StereoCapture& capture = *parts_->capture;
  const TimeNs t_start_ns = parts_->sys->now_ns();
  bool assessed = false;
  while (!stop.load(std::memory_order_acquire)) {
    const TimeNs now_ns = parts_->sys->now_ns();
    if (now_ns >= until_ns) break;
    capture.run_once(50 * kNsPerMs);  // bounded so a stop request is seen within 50 ms
    if (!assessed && now_ns - t_start_ns >= kSyncWindowNs) {
      assessed = true;
      report_sync();
    }
  }
  capture.stop();
}

void LiveStereo::report_sync() {
  const drivers::StereoCapture& capture = *parts_->capture;
  const sync::SyncAssessment a = sync::assess_sync(capture.pairing(), capture.tolerance_ns());
  parts_->sync = a;  // allocation-free: a value in storage made at construction
  const double window_s = ns_to_s(kSyncWindowNs);
  const char* rig = parts_->trigger ? "triggered cameras" : "free-running cameras (no trigger)";
  static constexpr const char* kLine =
      "stereo sync over the first %g s: %.1f %% of %lld frames paired, skew mean %.1f ms, "
      "max %.1f ms (tolerance %g ms)";
  static constexpr const char* kLowPairing =
      "WARNING: cameras (%s): only %.1f %% of the frames pair (under 90 %%): check that both "
      "run at the board's cameras.*.fps and that cameras.sync_tolerance_ms suits it";
  static constexpr const char* kHighSkew =
      "WARNING: cameras (%s): stereo pairs up to %.1f ms apart (over half of "
      "cameras.sync_tolerance_ms, %g ms) from %s: the tracker triangulates unsynchronised "
      "images, depth errs with motion";
  static constexpr const char* kFreeRunning =
      "%s: the tracker triangulates images up to %.1f ms apart";
  const auto frames = static_cast<long long>(a.frames);
  // A record for the log thread on the appliance; a line here for record.
  const auto say = [this](const char* format, std::initializer_list<LogArg> args) {
    post_or_log(
        parts_->ring, [this](const std::string& l) { parts_->log("wallar: " + l); }, format, args,
        parts_->pair.c_str());
  };
  say(kLine, {window_s, a.paired_percent, frames, a.mean_skew_ms, a.max_skew_ms, a.tolerance_ms});
  if (a.low_pairing) say(kLowPairing, {LogArg::copied(), a.paired_percent});
  if (a.high_skew) {
    say(kHighSkew, {LogArg::copied(), a.max_skew_ms, a.tolerance_ms, rig});
  } else if (!parts_->trigger) {
    say(kFreeRunning, {rig, a.max_skew_ms});
  }
}

}  // namespace wallar::firmware
