// SPDX-License-Identifier: Apache-2.0
/// @file board_devices.cpp
/// @brief A live board's devices resolved by stable name, and its camera modes checked
/// against the calibration.
#include "wallar/firmware/board_devices.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <system_error>

#include "wallar/core/error.hpp"
#include "wallar/drivers/bus/i2c_recovery.hpp"
#include "wallar/drivers/camera/v4l2_camera.hpp"
#include "wallar/drivers/camera/v4l2_modes.hpp"
#include "wallar/drivers/recording/calibration_files.hpp"

namespace wallar::firmware {
namespace fs = std::filesystem;
namespace {

const char* const kCameraKey[2] = {"cameras.left", "cameras.right"};

class Resolver {
 public:
  Resolver(const drivers::DeviceTree& tree, BoardCheck* check) : tree_(tree), check_(check) {}

  // A device node found (its resolved node in *node_out); false, with the problem recorded,
  // when it cannot be.
  bool node(const std::string& key, const std::string& path, std::string* node_out = nullptr) {
    try {
      const drivers::ResolvedNode r = drivers::resolve_device_node(path, tree_);
      check_->found.push_back({key, r.describe()});
      if (node_out != nullptr) *node_out = r.node;
      return true;
    } catch (const DeviceError& e) {
      check_->problems.push_back({key + ": " + e.what(), false});
      return false;
    }
  }

  // A GPIO line's chip, replaced by its path; its line offset checked against the chip.
  void gpio(const std::string& key, GpioLine* line) {
    try {
      const drivers::ResolvedGpioChip chip = drivers::resolve_gpio_chip(line->chip, tree_);
      if (line->line >= 0 && static_cast<unsigned>(line->line) >= chip.info.lines) {
        check_->problems.push_back({key + ".line: " + std::to_string(line->line) + " is not on " +
                                        chip.describe() + " (lines 0.." +
                                        std::to_string(chip.info.lines - 1) + ")",
                                    true});
        return;
      }
      check_->found.push_back(
          {key + ".chip", chip.describe() + ", line " + std::to_string(line->line)});
      line->chip = chip.path;
    } catch (const DeviceError& e) {
      check_->problems.push_back({key + ".chip: " + e.what(), false});
    }
  }

 private:
  const drivers::DeviceTree& tree_;
  BoardCheck* check_;
};

std::string hz(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

bool BoardCheck::any_bad_input() const {
  return std::any_of(problems.begin(), problems.end(),
                     [](const Problem& p) { return p.bad_input; });
}

fs::path calibration_in(const BoardConfig& board, const drivers::DeviceTree& tree) {
  if (!board.calibration) return {};
  const fs::path& p = *board.calibration;
  // The loader made relative paths absolute against the board file's folder.
  const fs::path folder = board.file.parent_path().lexically_normal();
  const fs::path rel = p.lexically_relative(folder);
  const bool beside_board = !folder.empty() && !rel.empty() && *rel.begin() != "..";
  return beside_board ? p : tree.host_path(p);
}

BoardConfig resolve_board_devices(const BoardConfig& board, const drivers::DeviceTree& tree,
                                  BoardCheck* check) {
  BoardConfig out = board;
  if (board.source != BoardConfig::Source::kLive) return out;
  Resolver r(tree, check);
  std::string nodes[2];
  for (int i = 0; i < 2; ++i) {
    const CameraConfig& c = board.cameras[i];
    const std::string key = std::string(kCameraKey[i]) + ".device";
    if (c.device.empty()) {
      check->problems.push_back({key + ": missing (a /dev/v4l/by-id or by-path link)", true});
      continue;
    }
    r.node(key, c.device, &nodes[i]);
  }
  if (!nodes[0].empty() && nodes[0] == nodes[1]) {
    check->problems.push_back({"cameras.right.device: " + board.cameras[1].device +
                                   " is the left camera's node too (" + nodes[0] + ")",
                               true});
  }
  if (out.camera_trigger) r.gpio("cameras.trigger", &*out.camera_trigger);
  std::string imu_node;
  if (board.imu.driver != "none" && !board.imu.bus.empty()) {
    r.node("imu.bus", board.imu.bus, &imu_node);
  }
  if (out.imu.data_ready) r.gpio("imu.data_ready", &*out.imu.data_ready);
  if (out.imu.bus_recovery) {
    ImuConfig::BusRecovery& rec = *out.imu.bus_recovery;
    if (rec.scl) r.gpio("imu.bus_recovery.scl", &*rec.scl);
    if (rec.sda) r.gpio("imu.bus_recovery.sda", &*rec.sda);
    if (rec.rebind && !imu_node.empty()) {
      // What the recovery would unbind and bind: the adapter's controller and its driver.
      try {
        drivers::I2cRecoveryConfig config;
        config.adapter = imu_node;
        config.sysfs_root = tree.host_path("/sys").string();
        const drivers::I2cRecovery recovery(config);
        check->found.push_back(
            {"imu.bus_recovery", "rebinds " + recovery.controller() + " (" +
                                     fs::path(recovery.driver_dir()).filename().string() + ")"});
      } catch (const DeviceError& e) {
        check->problems.push_back({std::string("imu.bus_recovery: ") + e.what(), false});
      }
    }
  }
  if (board.display.backend == "kms") r.node("display.card", board.display.card);
  if (out.reset_button) r.gpio("input.reset_button", &*out.reset_button);
  if (out.exit_button) r.gpio("input.exit_button", &*out.exit_button);
  if (!board.keys.empty() && board.keys.front() == '/') r.node("input.keys", board.keys);
  if (board.calibration) {
    const fs::path p = calibration_in(board, tree);
    std::error_code ec;
    if (fs::exists(p, ec)) {
      check->found.push_back({"calibration", board.calibration->string()});
      out.calibration = p;
    } else {
      check->problems.push_back(
          {"calibration: " + board.calibration->string() + ": no such file or folder", true});
    }
  } else {
    check->problems.push_back(
        {"calibration: missing (a live board needs the rig's intrinsics and extrinsics)", true});
  }
  return out;
}

void check_rig(const BoardConfig& board, const RigCalibration& rig, const std::string& rig_source,
               BoardCheck* check) {
  if (board.source != BoardConfig::Source::kLive) return;
  if (board.imu.driver != "none" && !rig.imu_extrinsic_known) {
    check->problems.push_back(
        {"calibration: " + rig_source +
             ": no camera-IMU transform (cam0.T_cam_imu) for the board's " + board.imu.driver +
             ": its gravity and rates would be taken in cam0's axes; calibrate it (Kalibr "
             "camchain-imucam) or add 'imu_aligned_with_cam0: true'",
         true});
  }
  for (int i = 0; i < 2; ++i) {
    const CameraConfig& c = board.cameras[i];
    const CameraCalibration& k = rig.cams[static_cast<std::size_t>(i)];
    const std::string key = kCameraKey[i];
    if (c.width_px != k.width_px || c.height_px != k.height_px) {
      check->problems.push_back(
          {key + ".width/height: " + std::to_string(c.width_px) + "x" +
               std::to_string(c.height_px) + " but " + rig_source + " calibrates " + k.name +
               " at " + std::to_string(k.width_px) + "x" + std::to_string(k.height_px) +
               " (calibrate at the mode the board captures, or capture at the calibrated one)",
           true});
    } else if (k.rate_hz > 0.0 && std::abs(c.fps - k.rate_hz) > 0.01 * k.rate_hz) {
      check->problems.push_back({key + ".fps: " + hz(c.fps) + " Hz but " + rig_source + " gives " +
                                     k.name + " " + hz(k.rate_hz) + " Hz",
                                 true});
    } else {
      check->found.push_back(
          {key + " mode", std::to_string(c.width_px) + "x" + std::to_string(c.height_px) + " " +
                              c.pixel_format + " @ " + hz(c.fps) + " Hz, as calibrated"});
    }
  }
}

namespace {

// Each camera found asked for its modes: the board's must be one of them.
void check_camera_modes(const BoardConfig& board, const drivers::DeviceTree& tree,
                        drivers::V4l2System& v4l2, BoardCheck* check) {
  for (int i = 0; i < 2; ++i) {
    const CameraConfig& c = board.cameras[i];
    if (c.device.empty()) continue;
    std::string node;
    try {
      node = drivers::resolve_device_node(c.device, tree).node;
    } catch (const DeviceError&) {
      continue;  // already a problem of its own
    }
    const std::string key = kCameraKey[i];
    std::vector<drivers::V4l2Mode> modes;
    try {
      modes = drivers::enumerate_v4l2_modes(v4l2, node);
    } catch (const DeviceError& e) {
      check->problems.push_back({key + ".device: " + e.what(), false});
      continue;
    }
    if (modes.empty()) continue;  // a device that enumerates nothing: nothing to hold it to
    const auto format = drivers::parse_camera_pixel_format(c.pixel_format);
    if (!format) continue;  // the board parser names it
    const std::uint32_t fourcc = drivers::fourcc_of(*format);
    char mode[96];
    std::snprintf(mode, sizeof mode, "%s %dx%d", c.pixel_format.c_str(), c.width_px, c.height_px);
    if (!drivers::offers_mode(modes, fourcc, c.width_px, c.height_px)) {
      check->problems.push_back({key + ".format/width/height: " + mode + " is not a mode of " +
                                     node + " (it offers " + drivers::describe_modes(modes) + ")",
                                 true});
      continue;
    }
    if (!drivers::offers_mode(modes, fourcc, c.width_px, c.height_px, c.fps)) {
      check->problems.push_back({key + ".fps: " + hz(c.fps) + " Hz is not offered by " + node +
                                     " at " + mode + " (it offers " +
                                     drivers::describe_modes(modes) + ")",
                                 true});
      continue;
    }
    check->found.push_back(
        {key + " mode on " + node, std::string(mode) + " @ " + hz(c.fps) + " Hz offered"});
  }
}

}  // namespace

BoardCheck check_board(const BoardConfig& board, const drivers::DeviceTree& tree,
                       drivers::V4l2System* v4l2) {
  BoardCheck check;
  check.resolved = board;
  if (board.source != BoardConfig::Source::kLive) {
    std::error_code ec;
    if (fs::exists(board.replay.recording, ec)) {
      check.found.push_back({"replay.recording", board.replay.recording.string()});
    } else {
      check.problems.push_back(
          {"replay.recording: " + board.replay.recording.string() + ": no such folder", true});
    }
    return check;
  }
  if (board.calibration) {
    const fs::path path = calibration_in(board, tree);
    std::error_code ec;
    if (fs::exists(path, ec)) {
      try {
        check_rig(board, recording::read_rig_calibration(path), board.calibration->string(),
                  &check);
      } catch (const InputError& e) {
        check.problems.push_back({std::string("calibration: ") + e.what(), true});
      }
    }
  }
  check.resolved = resolve_board_devices(board, tree, &check);
  if (v4l2 != nullptr) check_camera_modes(board, tree, *v4l2, &check);
  return check;
}

BoardConfig check_sensor_board(const BoardConfig& board, const drivers::DeviceTree& tree,
                               std::initializer_list<std::string_view> keys,
                               const std::function<void(const std::string&)>& log) {
  if (board.source != BoardConfig::Source::kLive) return board;
  BoardCheck all;
  if (board.calibration) {
    const fs::path p = calibration_in(board, tree);
    std::error_code ec;
    if (fs::exists(p, ec)) {
      check_rig(board, recording::read_rig_calibration(p), board.calibration->string(), &all);
    }
  }
  BoardConfig out = resolve_board_devices(board, tree, &all);
  const bool cameras = std::find(keys.begin(), keys.end(), "cameras") != keys.end();
  const auto wanted = [&](const std::string& line) {
    if (line.rfind("calibration: ", 0) == 0) {
      // A calibration the board names must be there where cameras are recorded (it goes into
      // the recording's sensor files); none, or one without the camera-IMU transform, is fine.
      return cameras && line.find(": no such file") != std::string::npos;
    }
    return std::any_of(keys.begin(), keys.end(),
                       [&](std::string_view k) { return line.rfind(k, 0) == 0; });
  };
  BoardCheck check;
  for (const BoardCheck::Problem& p : all.problems) {
    if (wanted(p.line)) check.problems.push_back(p);
  }
  throw_if_failed(board, check, log);
  return out;
}

void throw_if_failed(const BoardConfig& board, const BoardCheck& check,
                     const std::function<void(const std::string&)>& log) {
  if (check.ok()) return;
  // The line thrown is the first contradiction in the board file when there is one: fixing a
  // file is the first step, and it decides the exit status (2, not 1).
  const bool bad_input = check.any_bad_input();
  const auto first =
      std::find_if(check.problems.begin(), check.problems.end(),
                   [&](const BoardCheck::Problem& p) { return p.bad_input == bad_input; });
  if (log) {
    for (auto p = check.problems.begin(); p != check.problems.end(); ++p) {
      if (p != first) log(board.file.string() + ": " + p->line);
    }
  }
  std::string what = board.file.string() + ": " + first->line;
  if (check.problems.size() > 1) {
    what += " (" + std::to_string(check.problems.size() - 1) + " more problem" +
            (check.problems.size() > 2 ? "s" : "") + " above)";
  }
  if (bad_input) throw InputError(what);
  throw DeviceError(what);
}

}  // namespace wallar::firmware
