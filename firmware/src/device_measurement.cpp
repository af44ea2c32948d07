// SPDX-License-Identifier: Apache-2.0
/// @file device_measurement.cpp
/// @brief The board's cameras and IMU run for a few seconds through LiveStereo and LiveImu.
#include "wallar/firmware/device_measurement.hpp"

#include <atomic>
#include <cstdio>
#include <exception>
#include <memory>
#include <thread>

#include "wallar/firmware/live_imu.hpp"
#include "wallar/firmware/live_stereo.hpp"

namespace wallar::firmware {
namespace {

// Samples and frames are counted by the modules themselves; nothing is kept here.
class DiscardSink final : public source::SensorSink, public drivers::ImuSampleSink {
 public:
  void on_imu(const ImuSample&) override {}
  void on_stereo(const StereoFrame&) override {}
  void on_imu_sample(const ImuSample&) noexcept override {}
};

std::string percent(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f %%", v);
  return buf;
}

std::string hz(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f Hz", v);
  return buf;
}

}  // namespace

DeviceMeasurement measure_devices(const BoardConfig& board, drivers::V4l2System& sys,
                                  const std::function<void(const std::string&)>& log,
                                  const DeviceMeasurementOptions& options) {
  DeviceMeasurement out;
  if (board.source != BoardConfig::Source::kLive) return out;
  const std::string cameras = "cameras (" + camera_pair_name(board) + ")";
  const std::atomic<bool> stop{false};
  DiscardSink sink;
  std::string camera_error, imu_error;
  std::unique_ptr<LiveImu> imu;
  if (options.imu && board.imu.driver != "none") {
    try {
      imu = std::make_unique<LiveImu>(board, sink);
      out.imu_nominal_hz = imu->nominal_rate_hz();
    } catch (const std::exception& e) {
      imu_error = e.what();
    }
  }
  std::thread imu_thread;
  if (imu) {
    imu_thread = std::thread([&] {
      try {
        imu->run(monotonic_now_ns() + options.imu_ns, stop);
      } catch (const std::exception& e) {  // a device that fails mid-run: a problem line
        imu_error = e.what();
      }
    });
  }
  try {
    LiveStereo stereo(board, sink, log, sys);
    stereo.run(sys.now_ns() + options.cameras_ns, stop);  // the cameras' clock
    out.sync = stereo.sync_assessment();
    for (int i = 0; i < 2; ++i) {
      const drivers::V4l2Camera& cam = stereo.capture().camera(i);
      out.counters.emplace_back(cam.config().name, drivers::format_counters(cam.counters()));
    }
  } catch (const std::exception& e) {
    camera_error = e.what();
  }
  if (imu_thread.joinable()) imu_thread.join();
  if (imu) {
    out.imu_rate_hz = imu->measured_rate_hz();
    out.counters.emplace_back("imu", drivers::format_counters(imu->driver().counters()));
  }

  if (!camera_error.empty()) out.problems.push_back(cameras + ": " + camera_error);
  if (camera_error.empty() && !out.sync) {
    out.problems.push_back(cameras + ": stopped before the pairing was measured");
  }
  if (out.sync && out.sync->low_pairing) {
    out.problems.push_back(cameras + ": " + percent(out.sync->paired_percent) +
                           " of the frames pair (under 90 %; cameras.*.fps, "
                           "cameras.sync_tolerance_ms)");
  }
  const std::string imu_name =
      "imu (" + (board.imu.bus.empty() ? "usb " + board.imu.usb_id : board.imu.bus) + ")";
  if (!imu_error.empty()) out.problems.push_back(imu_name + ": " + imu_error);
  if (imu && !out.imu_rate_hz) {
    out.problems.push_back(imu_name + ": no rate measured (the run stopped first)");
  } else if (imu && !rate_ok(*out.imu_rate_hz, out.imu_nominal_hz)) {
    out.problems.push_back(imu_name + ": " + hz(*out.imu_rate_hz) + " delivered, not " +
                           hz(out.imu_nominal_hz) + " (imu.rate_hz)");
  }
  return out;
}

}  // namespace wallar::firmware
