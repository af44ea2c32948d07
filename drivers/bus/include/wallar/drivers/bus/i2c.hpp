// SPDX-License-Identifier: Apache-2.0
/// @file i2c.hpp
/// @brief One narrow I2C interface, its Linux implementation over /dev/i2c-N (I2C_RDWR) and the
/// seam below it that a register-level simulator implements in tests.
///
/// Layers, top to bottom:
///   - I2cDevice: one device at one address; transfer(tx, rx) is a write followed by a read in
///     ONE combined transaction (repeated start), returning 0 or a positive errno.
///   - I2cBus: the I2cDevice a driver gets. Builds the i2c_msg pair and i2c_rdwr_ioctl_data
///     exactly as the kernel wants them, retries what is worth retrying, detects short
///     transfers, counts, and calls a bus-recovery hook after persistent failure.
///   - I2cAdapter: the seam. LinuxI2cAdapter calls ::ioctl(fd, I2C_RDWR, &data); the test
///     simulator receives the very same struct and answers it from its register file.
///
/// Error codes the caller sees (positive errno):
///   - ENXIO / EREMOTEIO: the device did not acknowledge (absent, unplugged, in reset). Not
///     retried: retrying a NACK only keeps the bus busy.
///   - EIO / EAGAIN / ETIMEDOUT: bus error, arbitration lost, clock stretching timeout. Retried
///     up to Options::max_retries times.
///   - EPROTO: a short transfer (the adapter completed fewer messages or bytes than asked);
///     the rx bytes are not to be trusted.
///   - anything else the kernel says, unchanged.
/// EINTR is retried transparently and never returned.
///
/// Threading: an I2cBus and its adapter belong to one thread (the thread of the driver that
/// owns the device); nothing here blocks beyond the kernel's transfer, nothing allocates in
/// transfer().
#pragma once

#include <linux/i2c-dev.h>
#include <linux/i2c.h>

#include <cerrno>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>

namespace wallar::drivers {

/// The errno an I2cBus returns for a short transfer (fewer messages or bytes than asked).
inline constexpr int kI2cShortTransfer = EPROTO;

/// True for the errno values that mean "the device did not acknowledge".
constexpr bool is_i2c_nack(int err) { return err == ENXIO || err == EREMOTEIO; }

/// One device on an I2C bus, the interface every I2C chip driver uses.
class I2cDevice {
 public:
  virtual ~I2cDevice() = default;
  /// Writes tx (may be empty) then reads rx.size() bytes (may be empty) in one combined
  /// transaction with a repeated start between the two. Returns 0 or a positive errno; on
  /// error the content of rx is unspecified.
  virtual int transfer(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) = 0;
};

/// The seam below I2cBus: executes one I2C_RDWR request. Returns the number of messages the
/// adapter completed (>= 0, what the ioctl returns) or a negative errno.
class I2cAdapter {
 public:
  virtual ~I2cAdapter() = default;
  virtual int rdwr(i2c_rdwr_ioctl_data& data) = 0;
};

/// A Linux I2C adapter, /dev/i2c-N. Opened O_RDWR | O_CLOEXEC at construction.
class LinuxI2cAdapter final : public I2cAdapter {
 public:
  /// Throws wallar::DeviceError "PATH: cannot open I2C adapter: STRERROR" (one line) when the
  /// device node cannot be opened, or does not support plain I2C transfers.
  explicit LinuxI2cAdapter(std::string path);
  ~LinuxI2cAdapter() override;
  LinuxI2cAdapter(const LinuxI2cAdapter&) = delete;
  LinuxI2cAdapter& operator=(const LinuxI2cAdapter&) = delete;

  int rdwr(i2c_rdwr_ioctl_data& data) override;
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

/// Per-bus counters (the driver keeps its own, per error class, on top).
struct I2cBusCounters {
  std::uint64_t transfers = 0;   //!< transfer() calls
  std::uint64_t failures = 0;    //!< transfer() calls that returned an error
  std::uint64_t retries = 0;     //!< extra attempts after EIO / EAGAIN / ETIMEDOUT
  std::uint64_t eintr = 0;       //!< attempts interrupted by a signal (retried)
  std::uint64_t recoveries = 0;  //!< times the recovery hook was called
};

/// What to do when the bus looks stuck. On a real board: clock SCL nine times through the
/// pin's GPIO function until the slave releases SDA, then issue a STOP; or unbind/bind the
/// adapter driver (echo the adapter to /sys/bus/platform/drivers/<drv>/unbind then bind), as
/// PX4 and the kernel's i2c_recover_bus() do. Called on the bus's thread; may block briefly.
using I2cRecoveryHook = std::function<void()>;

/// The Linux implementation of I2cDevice on top of an adapter (real or simulated).
class I2cBus final : public I2cDevice {
 public:
  struct Options {
    int max_retries = 2;         //!< extra attempts on EIO / EAGAIN / ETIMEDOUT
    int max_eintr_retries = 16;  //!< bound on EINTR restarts (a signal storm is an error)
    int recover_after = 8;       //!< consecutive failed transfer() calls before recovery
  };

  /// adapter must outlive the bus. address: 7-bit device address.
  I2cBus(I2cAdapter& adapter, std::uint16_t address, Options options,
         I2cRecoveryHook recovery = {});
  I2cBus(I2cAdapter& adapter, std::uint16_t address) : I2cBus(adapter, address, Options{}) {}

  int transfer(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) override;

  [[nodiscard]] const I2cBusCounters& counters() const { return counters_; }
  [[nodiscard]] std::uint16_t address() const { return address_; }

 private:
  int attempt(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx);

  I2cAdapter& adapter_;
  std::uint16_t address_;
  Options options_;
  I2cRecoveryHook recovery_;
  I2cBusCounters counters_;
  int consecutive_failures_ = 0;
};

}  // namespace wallar::drivers
