// SPDX-License-Identifier: Apache-2.0
/// @file live_module.hpp
/// @brief The live source module: the board's stereo cameras on the capture thread
/// (LiveStereo: V4L2, pairing) and its IMU, if any, on the imu thread (LiveImu). The devices
/// open in start(), before any thread, so a missing one is an error at start.
///
/// Threading: as SourceModule.
#pragma once

#include <atomic>
#include <memory>

#include "wallar/firmware/appliance/source_module.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/live_imu.hpp"
#include "wallar/firmware/live_stereo.hpp"

namespace wallar::firmware {

class LiveModule final : public SourceModule {
 public:
  /// `log` (may be null) takes the capture thread's camera state changes as records.
  explicit LiveModule(const BoardConfig& board, LogRing* log = nullptr)
      : board_(board), log_(log) {}
  void start(source::SensorSink& sink, drivers::ImuSampleSink& imu_sink, bool realtime,
             const std::atomic<bool>& stop) override;
  [[nodiscard]] bool finished() const override { return capture_done_.load() && imu_done_.load(); }
  bool join_within(DurationNs timeout_ns) override;
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::vector<const RtThread*> threads() const override;
  [[nodiscard]] const std::atomic<std::uint64_t>* allocations_of(
      const RtThread* thread) const override;
  [[nodiscard]] std::vector<std::pair<const char*, const Heartbeat*>> heartbeats() const override;
  [[nodiscard]] std::exception_ptr error() const override;
  [[nodiscard]] std::vector<std::pair<std::string, std::string>> device_counters() const override;

 private:
  const BoardConfig& board_;
  LogRing* log_;
  std::unique_ptr<LiveStereo> cameras_;
  std::unique_ptr<LiveImu> imu_;
  std::unique_ptr<RtThread> capture_, imu_thread_;
  std::atomic<std::uint64_t> capture_allocs_{0}, imu_allocs_{0};  // after the devices opened
  std::atomic<bool> capture_done_{false}, imu_done_{false};
};

}  // namespace wallar::firmware
