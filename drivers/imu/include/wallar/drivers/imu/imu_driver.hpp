// SPDX-License-Identifier: Apache-2.0
/// @file imu_driver.hpp
/// @brief What every IMU driver shares: the state machine's states, the error counters, the
/// sample sink and the non-blocking step interface.
///
/// A driver is an explicit state machine RESET -> WAIT_FOR_RESET -> CONFIGURE -> RUN
/// (PX4's InvenSense drivers): step() never sleeps, it does what is due and says when it
/// wants to run next. A failure counter counts up on every failed transfer and down on every
/// good one; when it passes the driver's limit the device is fully reset. Every error class
/// has its own counter, printable on demand.
///
/// Threading: a driver and its bus belong to one thread (the imu thread); step() is not
/// re-entrant. counters() may be copied by that thread for a supervisor snapshot. The sink is
/// called on the driver's thread and must not block (the firmware's sink is an SPSC ring).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "wallar/core/imu_sample.hpp"
#include "wallar/core/time.hpp"

namespace wallar::drivers {

enum class ImuDriverState : std::uint8_t { kReset, kWaitForReset, kConfigure, kRun };

constexpr std::string_view to_string(ImuDriverState s) {
  switch (s) {
    case ImuDriverState::kReset: return "RESET";
    case ImuDriverState::kWaitForReset: return "WAIT_FOR_RESET";
    case ImuDriverState::kConfigure: return "CONFIGURE";
    case ImuDriverState::kRun: return "RUN";
  }
  return "?";
}

/// One counter per error class (and the good traffic, so rates can be computed).
struct ImuCounters {
  std::uint64_t samples = 0;            //!< samples handed to the sink
  std::uint64_t bad_transfer = 0;       //!< transfers that failed (EIO, timeout, ...)
  std::uint64_t nack = 0;               //!< I2C transfers the device did not acknowledge
  std::uint64_t short_transfer = 0;     //!< fewer bytes than asked for
  std::uint64_t fifo_overflow = 0;      //!< FIFO overflows (samples were lost on the chip)
  std::uint64_t dropped_samples = 0;    //!< samples known lost (overflow, resync, bad frame)
  std::uint64_t missed_data_ready = 0;  //!< data-ready edges that did not come when due
  std::uint64_t resync = 0;             //!< times the driver re-found the frame or FIFO start
  std::uint64_t config_mismatch = 0;    //!< configuration registers found changed
  std::uint64_t resets = 0;             //!< full device resets after the first
  std::uint64_t probe_failures = 0;     //!< WHO_AM_I / chip id did not answer or was wrong
};

/// "samples=.. bad_transfer=.. ..." on one line, every counter named.
std::string format_counters(const ImuCounters& c);

/// Where a driver puts its samples. Called on the driver's thread; must not block or throw.
class ImuSampleSink {
 public:
  virtual ~ImuSampleSink() = default;
  virtual void on_imu_sample(const ImuSample& sample) noexcept = 0;
};

/// The non-blocking driver interface the imu thread runs.
class ImuDriver {
 public:
  virtual ~ImuDriver() = default;
  /// Does whatever is due at `now_ns` (CLOCK_MONOTONIC). `data_ready_ns` is the kernel
  /// timestamp of the data-ready edge that woke the caller (nullopt when it woke on its
  /// timeout or has no interrupt line). Returns the monotonic time at which it wants to
  /// run again at the latest.
  virtual TimeNs step(TimeNs now_ns, std::optional<TimeNs> data_ready_ns) = 0;
  [[nodiscard]] virtual ImuDriverState state() const = 0;
  [[nodiscard]] virtual const ImuCounters& counters() const = 0;
  [[nodiscard]] virtual std::string_view name() const = 0;
};

}  // namespace wallar::drivers
