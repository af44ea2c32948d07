// SPDX-License-Identifier: Apache-2.0
/// @file live_stereo.hpp
/// @brief The board's two cameras, opened live: V4L2 capture on real devices, the trigger line
/// when the board has one, the USB reset rung through libusb, and the capture thread's loop.
///
/// State changes are logged once each, on stderr by default: a camera that stalls or falls off
/// the bus is announced with what the pipeline does meanwhile (no stereo pairs; the IMU stream
/// goes on), and its return likewise.
///
/// Threading: a LiveStereo belongs to the thread that calls run() (the capture thread); `stop`
/// is the only thing other threads touch. The sink is called on that thread.
#pragma once

#include <array>
#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "wallar/drivers/camera/stereo_capture.hpp"
#include "wallar/drivers/camera/v4l2_system.hpp"
#include "wallar/drivers/sync/stereo_pairer.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/log_ring.hpp"

namespace wallar::firmware {

/// The driver configuration of the board's cameras (left, right). Throws InputError naming
/// the board file when a camera is incompletely described.
std::array<drivers::V4l2CameraConfig, 2> camera_configs(const BoardConfig& board);

/// "left DEVICE, right DEVICE": how the pair's lines name the board's two cameras.
std::string camera_pair_name(const BoardConfig& board);

class LiveStereo {
 public:
  using Log = std::function<void(const std::string& line)>;

  /// Opens and starts both cameras (and the trigger line). Throws DeviceError naming the camera
  /// and device when one cannot be opened or refuses the board's format. `sys` must outlive
  /// every frame delivered (frames may outlive this object): the product's never dies.
  /// `ring` (may be null): camera state changes are posted there as records instead of `log`
  /// lines, so the capture thread (SCHED_FIFO) formats nothing.
  LiveStereo(const BoardConfig& board, source::SensorSink& sink, Log log = {},
             drivers::V4l2System& sys = drivers::linux_v4l2_system(), LogRing* ring = nullptr);
  ~LiveStereo();
  LiveStereo(const LiveStereo&) = delete;
  LiveStereo& operator=(const LiveStereo&) = delete;

  /// Captures until `until_ns` (CLOCK_MONOTONIC) or `stop`, then stops the cameras. After the
  /// first kSyncWindowNs it says how well the pair is synchronised (sync::assess_sync): the
  /// paired share and the skew, a warning under 90 % paired or above half the tolerance, and
  /// for free-running cameras that the tracker triangulates images taken that far apart.
  void run(TimeNs until_ns, const std::atomic<bool>& stop);
  static constexpr DurationNs kSyncWindowNs = 3 * kNsPerS;

  [[nodiscard]] const drivers::StereoCapture& capture() const;
  /// What run() measured over its first kSyncWindowNs (none before; `wallar run --check`).
  [[nodiscard]] const std::optional<sync::SyncAssessment>& sync_assessment() const;
  /// "left /dev/video0 640x480 YUYV 30.0 Hz (uvcvideo); right ..."
  [[nodiscard]] std::string description() const;

 private:
  void report_sync();

  struct Parts;
  std::unique_ptr<Parts> parts_;
};

}  // namespace wallar::firmware
