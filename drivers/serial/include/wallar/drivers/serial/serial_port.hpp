// SPDX-License-Identifier: Apache-2.0
/// @file serial_port.hpp
/// @brief A raw, non-blocking serial port over termios (8N1, no flow control, poll timeouts).
///
/// Opening and configuring may throw (start-up); reading, writing and flushing never throw
/// and never allocate: they return the number of bytes moved and an errno value, so a
/// fixed-rate driver can count failures instead of unwinding. Errors that are thrown name the
/// device path and strerror on one line.
///
/// Threading: one owner thread. fd() may be handed to that thread's poll(); the port itself
/// is not shared. Move-only; the destructor closes the descriptor.
#pragma once

#include <termios.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

#include "wallar/core/error.hpp"
#include "wallar/core/time.hpp"

namespace wallar::drivers {

/// The device could not be opened or configured (missing, busy, not a tty): not bad input
/// but a missing or broken device. The message names the path and strerror.
class SerialError : public DeviceError {
 public:
  using DeviceError::DeviceError;
};

/// The termios speed constant of a standard baud rate, nullopt when the kernel has none.
[[nodiscard]] std::optional<speed_t> baud_to_speed(int baud);

/// Time one byte takes on the wire at `baud` with 8N1 framing (start + 8 data + stop bits).
[[nodiscard]] constexpr DurationNs serial_byte_time_ns(int baud) {
  return baud > 0 ? (10 * kNsPerS + baud - 1) / baud : 0;
}

/// Bytes moved and the errno of the failure that stopped the operation (0 = none;
/// ETIMEDOUT = the timeout or deadline passed first; EIO/ENXIO/ENODEV = the device is gone).
struct SerialIo {
  std::size_t bytes = 0;
  int error = 0;
  [[nodiscard]] bool ok() const { return error == 0; }
};

enum class SerialFlush : std::uint8_t { kInput, kOutput, kBoth };

class SerialPort {
 public:
  /// Opens `path` (O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC) in raw 8N1 mode at `baud`
  /// without flow control. Throws wallar::InputError for a baud rate the kernel has no
  /// constant for ("<path>: unsupported baud rate <baud> ..."), SerialError when the device
  /// cannot be opened or configured ("<path>: open: No such file or directory").
  SerialPort(std::string path, int baud);
  ~SerialPort();
  SerialPort(SerialPort&& other) noexcept;
  SerialPort& operator=(SerialPort&& other) noexcept;
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  /// Reads what is available into `buf`, waiting up to `timeout_ns` for the first byte
  /// (0: do not wait). Returns bytes > 0, or bytes == 0 with error ETIMEDOUT when nothing
  /// came, or the errno of a failed read/poll. EINTR is retried within the timeout.
  SerialIo read_some(std::span<std::uint8_t> buf, DurationNs timeout_ns);

  /// Writes the whole buffer, waiting for room in the kernel's buffer until `timeout_ns`
  /// has passed (a deadline for the whole buffer, not per write). On failure bytes says how
  /// much went out. EINTR is retried.
  SerialIo write_all(std::span<const std::uint8_t> data, DurationNs timeout_ns);

  /// Discards bytes received but not read and/or written but not sent (tcflush). Returns 0
  /// or errno.
  int flush(SerialFlush which);

  /// Bytes written but not yet sent on the wire (TIOCOUTQ), or -1 with errno on failure.
  [[nodiscard]] int output_pending() const;

  [[nodiscard]] int fd() const { return fd_; }
  [[nodiscard]] const std::string& path() const { return path_; }
  [[nodiscard]] int baud() const { return baud_; }
  [[nodiscard]] DurationNs byte_time_ns() const { return serial_byte_time_ns(baud_); }
  /// "<path>: <what>: <strerror(err)>" for a caller that wants to report a failure (allocates).
  [[nodiscard]] std::string describe(std::string_view what, int err) const;

 private:
  void close_fd() noexcept;

  std::string path_;
  int baud_ = 0;
  int fd_ = -1;
};

}  // namespace wallar::drivers
