// SPDX-License-Identifier: Apache-2.0
/// @file serial_port.cpp
/// @brief termios raw mode, poll() timeouts and EINTR handling for SerialPort.
#include "wallar/drivers/serial/serial_port.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <utility>

#include "wallar/core/error.hpp"

namespace wallar::drivers {
namespace {

struct BaudEntry {
  int baud;
  speed_t speed;
};

// Every rate Linux has a Bnnn constant for (termios-baud.h); anything else needs BOTHER
// (termios2), which no device of this project uses.
constexpr std::array<BaudEntry, 30> kBaudTable{{
    {50, B50},           {75, B75},           {110, B110},         {134, B134},
    {150, B150},         {200, B200},         {300, B300},         {600, B600},
    {1200, B1200},       {1800, B1800},       {2400, B2400},       {4800, B4800},
    {9600, B9600},       {19200, B19200},     {38400, B38400},     {57600, B57600},
    {115200, B115200},   {230400, B230400},   {460800, B460800},   {500000, B500000},
    {576000, B576000},   {921600, B921600},   {1000000, B1000000}, {1152000, B1152000},
    {1500000, B1500000}, {2000000, B2000000}, {2500000, B2500000}, {3000000, B3000000},
    {3500000, B3500000}, {4000000, B4000000},
}};

// Milliseconds for poll(), rounded up so a 0.5 ms timeout still waits, capped at INT_MAX.
int poll_ms(DurationNs remaining_ns) {
  if (remaining_ns <= 0) return 0;
  const DurationNs ms = (remaining_ns + kNsPerMs - 1) / kNsPerMs;
  return ms > 0x7fffffff ? 0x7fffffff : static_cast<int>(ms);
}

// Waits until fd has `events` or the deadline passes: 0 ready, ETIMEDOUT, or errno.
int wait_for(int fd, short events, TimeNs deadline_ns) {
  for (;;) {
    pollfd p{fd, events, 0};
    const int n = ::poll(&p, 1, poll_ms(deadline_ns - monotonic_now_ns()));
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (n == 0) {
      if (monotonic_now_ns() >= deadline_ns) return ETIMEDOUT;
      continue;  // poll's millisecond rounding woke us early
    }
    if ((p.revents & POLLNVAL) != 0) return EBADF;
    // POLLHUP/POLLERR: let the read or write report the real errno (EIO on a hung-up tty).
    return 0;
  }
}

}  // namespace

std::optional<speed_t> baud_to_speed(int baud) {
  for (const BaudEntry& e : kBaudTable) {
    if (e.baud == baud) return e.speed;
  }
  return std::nullopt;
}

SerialPort::SerialPort(std::string path, int baud) : path_(std::move(path)), baud_(baud) {
  const std::optional<speed_t> speed = baud_to_speed(baud);
  if (!speed) {
    throw_input_error(printable(path_, 200), 0,
                      "unsupported baud rate " + std::to_string(baud) +
                          " (standard rates only, e.g. 9600, 115200, 921600)");
  }
  do {
    fd_ = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  } while (fd_ < 0 && errno == EINTR);
  if (fd_ < 0) throw SerialError(describe("open", errno));

  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) {
    const int err = errno;
    close_fd();
    throw SerialError(describe("tcgetattr (not a tty?)", err));
  }
  ::cfmakeraw(&tio);  // no echo, no canonical mode, no signals, no CR/NL mapping, 8 bits
  tio.c_cflag &= ~(static_cast<tcflag_t>(CSTOPB) | static_cast<tcflag_t>(PARENB) |
                   static_cast<tcflag_t>(CRTSCTS) | static_cast<tcflag_t>(CSIZE));
  tio.c_cflag |= (CS8 | CLOCAL | CREAD);
  tio.c_iflag &=
      ~(static_cast<tcflag_t>(IXON) | static_cast<tcflag_t>(IXOFF) | static_cast<tcflag_t>(IXANY));
  // VMIN 1: with O_NONBLOCK an empty line reads EAGAIN (VMIN 0 would read 0, which could not
  // be told from a hang-up); poll() does the waiting.
  tio.c_cc[VMIN] = 1;
  tio.c_cc[VTIME] = 0;
  if (::cfsetispeed(&tio, *speed) != 0 || ::cfsetospeed(&tio, *speed) != 0 ||
      ::tcsetattr(fd_, TCSANOW, &tio) != 0) {
    const int err = errno;
    close_fd();
    throw SerialError(describe("tcsetattr " + std::to_string(baud) + " 8N1 raw", err));
  }
  ::tcflush(fd_, TCIOFLUSH);  // nothing from before we owned the line
}

SerialPort::~SerialPort() { close_fd(); }

SerialPort::SerialPort(SerialPort&& other) noexcept
    : path_(std::move(other.path_)), baud_(other.baud_), fd_(std::exchange(other.fd_, -1)) {}

SerialPort& SerialPort::operator=(SerialPort&& other) noexcept {
  if (this != &other) {
    close_fd();
    path_ = std::move(other.path_);
    baud_ = other.baud_;
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

void SerialPort::close_fd() noexcept {
  if (fd_ >= 0) ::close(fd_);  // no retry on EINTR: on Linux the descriptor is gone anyway
  fd_ = -1;
}

SerialIo SerialPort::read_some(std::span<std::uint8_t> buf, DurationNs timeout_ns) {
  if (fd_ < 0) return {0, EBADF};
  if (buf.empty()) return {};
  const TimeNs deadline_ns = monotonic_now_ns() + (timeout_ns > 0 ? timeout_ns : 0);
  for (;;) {
    const ssize_t n = ::read(fd_, buf.data(), buf.size());
    if (n > 0) return {static_cast<std::size_t>(n), 0};
    if (n == 0) return {0, EIO};  // end of file on a tty: the other side hung up
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) return {0, errno};
    if (timeout_ns <= 0) return {0, ETIMEDOUT};
    if (const int err = wait_for(fd_, POLLIN, deadline_ns); err != 0) return {0, err};
  }
}

SerialIo SerialPort::write_all(std::span<const std::uint8_t> data, DurationNs timeout_ns) {
  if (fd_ < 0) return {0, EBADF};
  const TimeNs deadline_ns = monotonic_now_ns() + (timeout_ns > 0 ? timeout_ns : 0);
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd_, data.data() + done, data.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) return {done, errno};
    if (const int err = wait_for(fd_, POLLOUT, deadline_ns); err != 0) return {done, err};
  }
  return {done, 0};
}

int SerialPort::flush(SerialFlush which) {
  if (fd_ < 0) return EBADF;
  const int queue = which == SerialFlush::kInput    ? TCIFLUSH
                    : which == SerialFlush::kOutput ? TCOFLUSH
                                                    : TCIOFLUSH;
  return ::tcflush(fd_, queue) == 0 ? 0 : errno;
}

int SerialPort::output_pending() const {
  int n = 0;
  if (fd_ < 0 || ::ioctl(fd_, TIOCOUTQ, &n) != 0) return -1;
  return n;
}

std::string SerialPort::describe(std::string_view what, int err) const {
  std::string s = printable(path_, 200);
  s += ": ";
  s += what;
  s += ": ";
  s += std::strerror(err);
  return s;
}

}  // namespace wallar::drivers
