// SPDX-License-Identifier: Apache-2.0
/// @file board_devices.hpp
/// @brief A live board's devices found before anything opens them, and its camera modes
/// checked against the calibration: what `wallar run` does at start and `wallar run --check`
/// reports.
///
/// Every device the board names (cameras, I2C or serial bus, GPIO chips of the data-ready
/// line, trigger and buttons, the DRM card, an evdev path) is resolved in a device tree
/// (drivers/devices/device_names.hpp): GPIO chips by label, udev links followed. Each failure
/// is one line that names the board file's key and the device. The camera modes
/// (cameras.left.width/height/fps) must be the calibration's: a board at 640x480 over a
/// 752x480 calibration would triangulate with the wrong intrinsics.
///
/// Nothing here is on a fixed-rate path. Threading: pure functions of their arguments.
#pragma once

#include <filesystem>
#include <functional>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/core/calibration.hpp"
#include "wallar/drivers/camera/v4l2_system.hpp"
#include "wallar/drivers/devices/device_names.hpp"
#include "wallar/firmware/board.hpp"

namespace wallar::firmware {

struct BoardCheck {
  struct Found {
    std::string key;    //!< "imu.data_ready.chip"
    std::string found;  //!< "pinctrl-rp1 -> /dev/gpiochip0 (54 lines, 'pinctrl-rp1')"
  };
  struct Problem {
    std::string line;  //!< "cameras.left.device: /dev/v4l/by-path/...: no such device"
    /// The board file contradicts itself or its calibration (exit 2); false: a device is
    /// absent or not what it should be (exit 1).
    bool bad_input = false;
  };
  std::vector<Found> found;
  std::vector<Problem> problems;
  /// The board with each device named as the product opens it (resolve_board_devices), as
  /// check_board() found it; a replay board as given.
  BoardConfig resolved;
  [[nodiscard]] bool ok() const { return problems.empty(); }
  [[nodiscard]] bool any_bad_input() const;
};

/// Where the board's calibration is read from in `tree`: a path the board file gave beside
/// itself (relative) is the host's; an absolute one is the tree's (/etc/wallar/...).
std::filesystem::path calibration_in(const BoardConfig& board, const drivers::DeviceTree& tree);

/// Resolves every device a live board names. Returns the board with each device named as the
/// product opens it (GPIO chips by path; links kept, they are what udev keeps stable), and
/// records what was found and each problem in `check`. A replay board has no devices.
BoardConfig resolve_board_devices(const BoardConfig& board, const drivers::DeviceTree& tree,
                                  BoardCheck* check);

/// The board against its rig calibration (read from `rig_source`): camera width and height
/// always, fps where the calibration gives a camera rate, and a camera-IMU transform when the
/// board has an IMU (without one, gravity and rates would be taken in cam0's axes). Problems
/// are bad input.
void check_rig(const BoardConfig& board, const RigCalibration& rig, const std::string& rig_source,
               BoardCheck* check);

/// Everything `wallar run --check` checks, without opening a device: a live board's
/// calibration read (where calibration_in() says) and checked against the board (check_rig),
/// then every device resolved. A replay board: its recording is there.
/// With `v4l2` (the system's for the system's tree, a fake's in tests), each camera found is
/// opened and asked what it offers (VIDIOC_ENUM_*): the board's format and size must be a mode
/// of it, and its rate one of that mode's (bad input: the board asks what the device cannot).
BoardCheck check_board(const BoardConfig& board, const drivers::DeviceTree& tree,
                       drivers::V4l2System* v4l2 = nullptr);

/// The start-up check of a command that opens some of a live board's sensors without
/// tracking (`wallar record`: cameras and IMU; `wallar imu`: the IMU): the devices under the
/// board keys that start with one of `keys` ("cameras", "imu") resolved, and, when the board
/// names a calibration, the camera modes checked against it. Neither a calibration nor a
/// camera-IMU transform is required: a recording made to calibrate has neither yet. Throws as
/// throw_if_failed; returns the board as the product opens it. A replay board is returned as
/// it is.
BoardConfig check_sensor_board(const BoardConfig& board, const drivers::DeviceTree& tree,
                               std::initializer_list<std::string_view> keys,
                               const std::function<void(const std::string&)>& log = {});

/// Throws the check's first problem with the board file's name (the first bad-input problem
/// as InputError when there is one, else DeviceError), after `log` said each other problem on
/// its own line.
void throw_if_failed(const BoardConfig& board, const BoardCheck& check,
                     const std::function<void(const std::string&)>& log = {});

}  // namespace wallar::firmware
