// SPDX-License-Identifier: Apache-2.0
/// @file live_imu.hpp
/// @brief The IMU a board file names, opened live: bus, data-ready line and chip driver, and
/// the loop that waits on the hardware and steps the driver.
///
/// icm20948: /dev/i2c-N through I2cBus (I2C_RDWR), the data-ready line through libgpiod (its
/// kernel edge timestamps become the sample times); without a data_ready line the driver
/// reads its FIFO on a timer. bno055: the serial port (a tty, or the tty of the USB-UART
/// bridge named by usb_id, found through libusb and sysfs).
///
/// Threading: a LiveImu belongs to the thread that calls run() (the imu thread); `stop` is
/// the only thing other threads touch. The sink is called on that thread.
#pragma once

#include <atomic>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "wallar/core/heartbeat.hpp"
#include "wallar/drivers/imu/imu_driver.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/log_ring.hpp"

namespace wallar::firmware {

/// A stream's rate measured once at start: over `window_ns` after its first sample, or 0 when
/// no sample came within `window_ns` of the first update. Allocation-free (the imu thread).
class StartupRate {
 public:
  explicit StartupRate(DurationNs window_ns) : window_ns_(window_ns) {}
  /// The stream's sample count at now_ns; the rate in Hz once, when it is known.
  std::optional<double> update(TimeNs now_ns, std::uint64_t samples);
  [[nodiscard]] bool done() const { return done_; }

 private:
  DurationNs window_ns_;
  TimeNs t_start_ns_ = -1;
  TimeNs t_first_ns_ = -1;
  std::uint64_t samples_at_first_ = 0;
  bool done_ = false;
};

/// Within 10 % of the nominal rate (a measured 0: nothing came).
[[nodiscard]] inline bool rate_ok(double measured_hz, double nominal_hz) {
  return measured_hz > 0.0 && std::abs(measured_hz / nominal_hz - 1.0) <= 0.1;
}

/// The start-up rate check's lines: the measured rate, and a warning naming `device` and the
/// board's key when it is more than 10 % off `nominal_hz` or 0 (nothing came). Into `ring`
/// when there is one (no formatting on the caller's thread; `driver_state` must be a
/// literal), else formatted for `fallback`.
void say_imu_rate(double window_s, double measured_hz, double nominal_hz, const char* device,
                  const char* driver_state, LogRing* ring,
                  const std::function<void(const std::string&)>& fallback);

class LiveImu {
 public:
  /// Opens the board's IMU. Throws InputError when the board names no IMU, and
  /// std::runtime_error (one line naming the device and the system's reason) when a device
  /// cannot be opened.
  /// `ring` (may be null): the start-up rate check is posted there (the imu thread runs
  /// SCHED_FIFO and formats nothing); without one it is a line on stderr.
  LiveImu(const BoardConfig& board, drivers::ImuSampleSink& sink, LogRing* ring = nullptr);
  ~LiveImu();
  LiveImu(const LiveImu&) = delete;
  LiveImu& operator=(const LiveImu&) = delete;

  /// Waits on the hardware (data-ready edge, serial bytes) or until the driver's next wake
  /// time, steps the driver, and repeats until `until_ns` (CLOCK_MONOTONIC) or `stop`. Over
  /// the kRateWindowNs after its first sample it measures the IMU's rate and says it, with a
  /// warning when it is more than 10 % off the nominal rate (or when no sample came at all).
  void run(TimeNs until_ns, const std::atomic<bool>& stop);
  static constexpr DurationNs kRateWindowNs = 3 * kNsPerS;
  /// The rate the driver runs the chip at (an ICM-20948 gives 1125 / (1 + divider) Hz).
  [[nodiscard]] double nominal_rate_hz() const { return nominal_rate_hz_; }

  [[nodiscard]] const drivers::ImuDriver& driver() const;
  /// "icm20948 on /dev/i2c-1 @0x68, data-ready gpiochip4:24" and the like.
  [[nodiscard]] const std::string& description() const { return description_; }
  /// The rate run() measured over its first kRateWindowNs after the first sample (0: none
  /// came); none before (`wallar run --check`).
  [[nodiscard]] std::optional<double> measured_rate_hz() const { return measured_rate_hz_; }
  /// Beats at every wait-and-step (at least every 100 ms), any thread: an imu thread stuck in
  /// a bus transfer reads as silent.
  [[nodiscard]] const Heartbeat& heartbeat() const { return heartbeat_; }

 private:
  void report_rate(double measured_hz);

  struct Parts;
  std::unique_ptr<Parts> parts_;
  LogRing* ring_ = nullptr;
  double nominal_rate_hz_ = 0.0;
  std::string description_;
  std::string device_;  // the bus or serial port, for the rate warnings
  std::optional<double> measured_rate_hz_;
  Heartbeat heartbeat_{Heartbeat::Kind::kLoop};
};

/// The tty of the first USB device with this VID:PID (serial IMUs on a USB-UART bridge).
/// Throws std::runtime_error naming the id when there is none or it has no tty.
std::string find_usb_tty(const std::string& usb_id);

}  // namespace wallar::firmware
