// SPDX-License-Identifier: Apache-2.0
/// @file i2c_recovery.hpp
/// @brief Freeing a stuck I2C bus from user space, as the kernel's i2c_recover_bus() does for
/// an adapter whose device tree gives it recovery GPIOs: release the adapter, clock SCL until
/// the slave lets SDA go and issue a STOP (the I2C specification's bus clear, UM10204 §3.1.16),
/// give the pins back to the adapter.
///
/// A slave stopped part-way through a read (a reset of the master, a glitch) holds SDA low
/// waiting for clocks that never come; every transfer then times out. Nine clocks finish any
/// byte it was sending; a STOP ends its transaction. The pins belong to the I2C controller
/// while its driver is bound, so the recovery first unbinds the adapter's platform driver
/// through sysfs, takes SCL and SDA as open-drain GPIO lines for the clocks, then binds the
/// driver again, which re-applies the pins' I2C function (the driver core selects the
/// "default" pinctrl state before probe) and resets the controller; the adapter's device node
/// is then opened afresh. Each step is optional: without GPIO lines the rebind alone resets
/// the controller; without a driver to rebind (an adapter that is not a platform device, a
/// bit-banged i2c-gpio bus whose lines are free) the clocks alone run.
///
/// Threading: run() is called on the bus's thread (the imu thread, from the I2cBus recovery
/// hook) and blocks for a few milliseconds. It is a fault path: libgpiod allocates when the
/// lines are requested; everything else (paths) is prepared at construction.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "wallar/drivers/bus/gpio.hpp"

namespace wallar::drivers {

/// The two lines of a bus, driven open-drain (set(true) releases the line to its pull-up).
class I2cLines {
 public:
  virtual ~I2cLines() = default;
  virtual void set_scl(bool high) = 0;
  virtual void set_sda(bool high) = 0;
  [[nodiscard]] virtual bool sda() = 0;
  /// Half a clock period (5 us: 100 kHz, the speed every slave accepts).
  virtual void half_period() = 0;
};

/// The bus clear: up to `max_clocks` SCL pulses until SDA reads high, then a STOP (SDA low to
/// high while SCL is high). Returns the number of clocks it took, or nullopt when SDA was still
/// low after them (a slave that is stuck for good, or a short to ground).
std::optional<int> i2c_bus_clear(I2cLines& lines, int max_clocks = 9);

/// Where the recovery finds what it needs.
struct I2cRecoveryConfig {
  std::string adapter;              //!< the adapter's device node: /dev/i2c-1 (or a link)
  std::optional<GpioLineSpec> scl;  //!< the bus's lines as GPIOs (both or neither)
  std::optional<GpioLineSpec> sda;
  bool rebind = true;               //!< unbind and bind the adapter's platform driver
  std::string sysfs_root = "/sys";  //!< tests point it at a fake tree
};

struct I2cRecoveryCounters {
  std::uint64_t runs = 0;
  std::uint64_t cleared = 0;         //!< bus clears that left SDA high
  std::uint64_t clear_failures = 0;  //!< SDA still low, or the lines could not be requested
  std::uint64_t rebinds = 0;         //!< unbind + bind that both succeeded
  std::uint64_t rebind_failures = 0;
};

/// The recovery a board file asks for (imu.bus_recovery), run by I2cBus's recovery hook.
class I2cRecovery {
 public:
  /// Resolves the adapter's controller and driver in sysfs (the adapter node's name, i2c-N,
  /// under SYSFS/bus/i2c/devices, its parent device and that device's driver). Throws
  /// wallar::DeviceError naming the adapter when a rebind is asked for and sysfs shows no
  /// driver to rebind, or when only one of scl and sda is given.
  explicit I2cRecovery(I2cRecoveryConfig config);

  /// Unbinds (when asked), clears the bus through the GPIO lines (when given), binds again.
  /// Returns true when every step it took succeeded. `reopen` runs after the bind, to open
  /// the adapter's node afresh (the old file descriptor belongs to the removed adapter).
  bool run(const std::function<void()>& reopen = {});

  [[nodiscard]] const I2cRecoveryCounters& counters() const { return counters_; }
  /// The controller device that is rebound ("1f00074000.i2c"), empty when none.
  [[nodiscard]] const std::string& controller() const { return controller_; }
  [[nodiscard]] const std::string& driver_dir() const { return driver_dir_; }

 private:
  bool clear_through_gpio();

  I2cRecoveryConfig config_;
  std::string controller_;  // the parent device's name, what unbind and bind take
  std::string driver_dir_;  // SYSFS/bus/platform/drivers/<driver> (resolved)
  I2cRecoveryCounters counters_;
};

}  // namespace wallar::drivers
