// SPDX-License-Identifier: Apache-2.0
/// @file device_measurement.hpp
/// @brief `wallar run --check` on the board's own devices: the cameras and the IMU opened and
/// run for a few seconds through the appliance's own live modules, so that the check sees what
/// the start-up checks of `wallar run` see (the stereo pair's pairing rate and skew, the IMU's
/// delivered rate), and each shortfall is a problem line naming the board key and the device.
///
/// Threading: measure_devices() runs the cameras and the IMU on two threads of its own and
/// returns when both are done; call it from one thread.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "wallar/core/time.hpp"
#include "wallar/drivers/camera/v4l2_system.hpp"
#include "wallar/drivers/sync/stereo_pairer.hpp"
#include "wallar/firmware/board.hpp"

namespace wallar::firmware {

struct DeviceMeasurement {
  std::optional<sync::SyncAssessment> sync;  //!< the cameras' first LiveStereo::kSyncWindowNs
  std::optional<double> imu_rate_hz;         //!< delivered (0: nothing came); none: no IMU
  double imu_nominal_hz = 0.0;
  /// The drivers' counters at the end ("left", "frames=.. reopens=.."), one line per device
  /// opened, as `wallar record` prints them (the HIL boot accounts for every IMU burst).
  std::vector<std::pair<std::string, std::string>> counters;
  /// One line each, naming the board key and the device: a camera or the IMU that could not
  /// be opened or started, under 90 % of the frames paired, an IMU rate 10 % off or none.
  std::vector<std::string> problems;
  [[nodiscard]] bool ok() const { return problems.empty(); }
};

struct DeviceMeasurementOptions {
  /// How long the cameras run: past the sync window, so that its assessment is made.
  DurationNs cameras_ns = 3500 * kNsPerMs;
  /// How long the IMU runs: its rate window after its first sample, which may come late.
  DurationNs imu_ns = 6500 * kNsPerMs;
  bool imu = true;  //!< false: the cameras only (the IMU is not opened)
};

/// Opens a live board's cameras (through `sys`) and IMU (the real bus or serial port), runs
/// them as the appliance's capture and imu threads do, and reports what they delivered. The
/// modules' own lines (the sync and rate lines, camera state changes) go to `log`. A replay
/// board has nothing to measure (an empty result).
DeviceMeasurement measure_devices(const BoardConfig& board, drivers::V4l2System& sys,
                                  const std::function<void(const std::string&)>& log,
                                  const DeviceMeasurementOptions& options = {});

}  // namespace wallar::firmware
