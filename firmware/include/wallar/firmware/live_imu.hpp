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
#include <memory>
#include <string>

#include "wallar/core/heartbeat.hpp"
#include "wallar/drivers/imu/imu_driver.hpp"
#include "wallar/firmware/board.hpp"

namespace wallar::firmware {

class LiveImu {
 public:
  /// Opens the board's IMU. Throws InputError when the board names no IMU, and
  /// std::runtime_error (one line naming the device and the system's reason) when a device
  /// cannot be opened.
  LiveImu(const BoardConfig& board, drivers::ImuSampleSink& sink);
  ~LiveImu();
  LiveImu(const LiveImu&) = delete;
  LiveImu& operator=(const LiveImu&) = delete;

  /// Waits on the hardware (data-ready edge, serial bytes) or until the driver's next wake
  /// time, steps the driver, and repeats until `until_ns` (CLOCK_MONOTONIC) or `stop`.
  void run(TimeNs until_ns, const std::atomic<bool>& stop);

  [[nodiscard]] const drivers::ImuDriver& driver() const;
  /// "icm20948 on /dev/i2c-1 @0x68, data-ready gpiochip4:24" and the like.
  [[nodiscard]] const std::string& description() const { return description_; }
  /// Beats at every wait-and-step (at least every 100 ms), any thread: an imu thread stuck in
  /// a bus transfer reads as silent.
  [[nodiscard]] const Heartbeat& heartbeat() const { return heartbeat_; }

 private:
  struct Parts;
  std::unique_ptr<Parts> parts_;
  std::string description_;
  Heartbeat heartbeat_{Heartbeat::Kind::kLoop};
};

/// The tty of the first USB device with this VID:PID (serial IMUs on a USB-UART bridge).
/// Throws std::runtime_error naming the id when there is none or it has no tty.
std::string find_usb_tty(const std::string& usb_id);

}  // namespace wallar::firmware
