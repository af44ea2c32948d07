// SPDX-License-Identifier: Apache-2.0
/// @file i2c.hpp
/// @brief One narrow I2C interface, its Linux implementation over /dev/i2c-N (I2C_RDWR, or SMBus
/// transactions on an adapter that has no plain I2C) and the seam below it that a
/// register-level simulator implements in tests.
///
/// Layers, top to bottom:
///   - I2cDevice: one device at one address; transfer(tx, rx) is a write followed by a read in
///     ONE combined transaction (repeated start), returning 0 or a positive errno.
///   - I2cBus: the I2cDevice a driver gets. Builds the i2c_msg pair and i2c_rdwr_ioctl_data
///     exactly as the kernel wants them, retries what is worth retrying, detects short
///     transfers, counts, and calls a bus-recovery hook after persistent failure.
///   - I2cAdapter: the seam. LinuxI2cAdapter calls ::ioctl(fd, I2C_RDWR, &data); the test
///     simulator receives the very same struct and answers it from its register file.
///   - On an SMBus-only adapter (no I2C_FUNC_I2C: a PC's SMBus controller, the kernel's
///     i2c-stub) LinuxI2cAdapter carries each request as the one SMBus transaction of the same
///     shape (rdwr_over_smbus): a register read of up to 32 bytes, a register write of up to
///     32 data bytes, a single byte. Other shapes (a read of 33 bytes or more, a write-only
///     message pair) fail with EOPNOTSUPP: SMBus cannot carry them.
///
/// Error codes the caller sees (positive errno):
///   - ENXIO / EREMOTEIO: the device did not acknowledge (absent, unplugged, in reset). Not
///     retried: retrying a NACK only keeps the bus busy.
///   - EIO / EAGAIN / ETIMEDOUT: bus error, arbitration lost, clock stretching timeout. Retried
///     up to Options::max_retries times by transfer(); never by transfer_once() (a read that
///     cannot be repeated: the failed attempt may already have taken bytes from a FIFO).
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
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>

namespace wallar::drivers {

/// The errno an I2cBus returns for a short transfer (fewer messages or bytes than asked).
inline constexpr int kI2cShortTransfer = EPROTO;

/// max_read_bytes() of a bus with no limit of its own below the I2C_RDWR message's.
inline constexpr std::size_t kI2cNoReadLimit = 65535;

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
  /// The same transaction, attempted once, for reads that cannot be repeated: a FIFO's data
  /// register hands out the next bytes on every read, a clear-on-read status clears. A failed
  /// attempt may have moved bytes on the chip before the error, so it is never retried; the
  /// caller resynchronises (empties the FIFO) instead.
  virtual int transfer_once(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) = 0;
  /// The most bytes one transfer() can read: an SMBus-only adapter carries 32 (an I2C block
  /// read), and a longer read fails with EOPNOTSUPP; a driver splits its bursts to fit.
  [[nodiscard]] virtual std::size_t max_read_bytes() const { return kI2cNoReadLimit; }
};

/// The seam below I2cBus: executes one I2C_RDWR request. Returns the number of messages the
/// adapter completed (>= 0, what the ioctl returns) or a negative errno.
class I2cAdapter {
 public:
  virtual ~I2cAdapter() = default;
  virtual int rdwr(i2c_rdwr_ioctl_data& data) = 0;
  /// The longest read message rdwr() carries (see I2cDevice::max_read_bytes).
  [[nodiscard]] virtual std::size_t max_read_bytes() const { return kI2cNoReadLimit; }
};

/// One SMBus transaction (what the I2C_SMBUS ioctl executes) for the device at `address`.
/// Returns 0 or a negative errno.
class SmbusPort {
 public:
  virtual ~SmbusPort() = default;
  virtual int smbus(std::uint16_t address, i2c_smbus_ioctl_data& call) = 0;
};

/// The largest register read or write (data bytes) an SMBus I2C-block transaction carries.
inline constexpr std::size_t kSmbusBlockMax = I2C_SMBUS_BLOCK_MAX;

/// Carries one I2C_RDWR request (one write, one read, or a write then a read, all to the same
/// address) as one SMBus transaction on an adapter with functionality `funcs` (I2C_FUNCS):
///   write 1 byte             -> send byte          (I2C_FUNC_SMBUS_WRITE_BYTE)
///   write 2 bytes            -> write byte data    (I2C_FUNC_SMBUS_WRITE_BYTE_DATA)
///   write 3..33 bytes        -> write I2C block    (I2C_FUNC_SMBUS_WRITE_I2C_BLOCK)
///   read 1 byte              -> receive byte       (I2C_FUNC_SMBUS_READ_BYTE)
///   write 1, read 1          -> read byte data     (I2C_FUNC_SMBUS_READ_BYTE_DATA)
///   write 1, read 2..32      -> read I2C block     (I2C_FUNC_SMBUS_READ_I2C_BLOCK)
/// The first byte written is the SMBus command (the register). Returns what I2C_RDWR would:
/// the number of messages done, or a negative errno; -EOPNOTSUPP for a shape the adapter's
/// SMBus functions cannot carry. Allocates nothing.
int rdwr_over_smbus(i2c_rdwr_ioctl_data& data, unsigned long funcs,  // NOLINT(google-runtime-int)
                    SmbusPort& port);

/// A Linux I2C adapter, /dev/i2c-N. Opened O_RDWR | O_CLOEXEC at construction. Plain I2C
/// (I2C_RDWR) where the adapter has it, otherwise SMBus transactions (rdwr_over_smbus).
class LinuxI2cAdapter final : public I2cAdapter, private SmbusPort {
 public:
  /// Throws wallar::DeviceError "PATH: cannot open I2C adapter: STRERROR" (one line) when the
  /// device node cannot be opened, or "PATH: neither plain-I2C nor SMBus register transfers
  /// (I2C_FUNCS ...)" when the adapter can carry neither.
  explicit LinuxI2cAdapter(std::string path);
  ~LinuxI2cAdapter() override;
  LinuxI2cAdapter(const LinuxI2cAdapter&) = delete;
  LinuxI2cAdapter& operator=(const LinuxI2cAdapter&) = delete;

  int rdwr(i2c_rdwr_ioctl_data& data) override;
  /// kSmbusBlockMax in SMBus mode (1 without I2C-block reads), else kI2cNoReadLimit.
  [[nodiscard]] std::size_t max_read_bytes() const override;
  [[nodiscard]] const std::string& path() const { return path_; }
  /// Closes the node and opens it again (after a bus recovery rebound the adapter: the old
  /// descriptor belongs to the removed one). False when it cannot be opened; transfers then
  /// fail with ENODEV until a later reopen() succeeds. Never throws; allocates nothing.
  bool reopen();
  /// True when the adapter has no plain I2C and requests go as SMBus transactions.
  [[nodiscard]] bool smbus_only() const { return smbus_only_; }

 private:
  int smbus(std::uint16_t address, i2c_smbus_ioctl_data& call) override;

  std::string path_;
  int fd_ = -1;
  unsigned long funcs_ = 0;  // NOLINT(google-runtime-int): I2C_FUNCS's own type
  bool smbus_only_ = false;
  int slave_address_ = -1;  //!< the address I2C_SLAVE last set (SMBus mode)
};

/// Per-bus counters (the driver keeps its own, per error class, on top).
struct I2cBusCounters {
  std::uint64_t transfers = 0;   //!< transfer() and transfer_once() calls
  std::uint64_t failures = 0;    //!< those that returned an error
  std::uint64_t retries = 0;     //!< extra attempts after EIO / EAGAIN / ETIMEDOUT
  std::uint64_t once = 0;        //!< transfer_once() calls (never retried)
  std::uint64_t eintr = 0;       //!< attempts interrupted by a signal (retried)
  std::uint64_t recoveries = 0;  //!< times the recovery hook was called
};

/// What to do when the bus looks stuck: on a board, I2cRecovery::run (i2c_recovery.hpp), which
/// unbinds the adapter's driver, clocks SCL until the slave releases SDA, issues a STOP and
/// binds the driver again, as the kernel's i2c_recover_bus() does. Called on the bus's thread;
/// may block briefly.
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
  int transfer_once(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) override;
  /// The adapter's.
  [[nodiscard]] std::size_t max_read_bytes() const override;

  [[nodiscard]] const I2cBusCounters& counters() const { return counters_; }
  [[nodiscard]] std::uint16_t address() const { return address_; }

 private:
  int attempt(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx);
  int transfer_with(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx, int retries);

  I2cAdapter& adapter_;
  std::uint16_t address_;
  Options options_;
  I2cRecoveryHook recovery_;
  I2cBusCounters counters_;
  int consecutive_failures_ = 0;
};

}  // namespace wallar::drivers
