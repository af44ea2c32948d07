// SPDX-License-Identifier: Apache-2.0
/// @file test_serial_port.cpp
/// @brief SerialPort over a real pseudo-terminal (raw mode, timeouts, EINTR, errors) and the
/// ByteRing resync helper.
#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <pty.h>
#include <sys/time.h>
#include <unistd.h>

#include <array>
#include <csignal>
#include <cstring>
#include <numeric>
#include <string>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/drivers/serial/byte_ring.hpp"
#include "wallar/drivers/serial/serial_port.hpp"

namespace wallar::drivers {
namespace {

using ::testing::HasSubstr;

// A pty pair: the test holds the master, the port opens the slave path.
class Pty {
 public:
  Pty() {
    char name[128] = {};
    if (::openpty(&master_, &slave_, name, nullptr, nullptr) != 0) ADD_FAILURE() << "openpty";
    path_ = name;
  }
  ~Pty() {
    ::close(master_);
    ::close(slave_);
  }
  [[nodiscard]] int master() const { return master_; }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  int master_ = -1;
  int slave_ = -1;
  std::string path_;
};

// Reads exactly n bytes from fd (blocking with poll, bounded).
std::vector<std::uint8_t> read_n(int fd, std::size_t n) {
  std::vector<std::uint8_t> out;
  while (out.size() < n) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) break;
    std::array<std::uint8_t, 512> buf{};
    const ssize_t got = ::read(fd, buf.data(), std::min(buf.size(), n - out.size()));
    if (got <= 0) break;
    out.insert(out.end(), buf.begin(), buf.begin() + got);
  }
  return out;
}

std::vector<std::uint8_t> all_bytes() {
  std::vector<std::uint8_t> v(256);
  std::iota(v.begin(), v.end(), std::uint8_t{0});
  return v;
}

TEST(SerialPort, RawModeTermiosIsSet) {
  Pty pty;
  SerialPort port(pty.path(), 115200);
  termios tio{};
  ASSERT_EQ(::tcgetattr(port.fd(), &tio), 0);
  EXPECT_EQ(tio.c_lflag & (ICANON | ECHO | ISIG | IEXTEN), 0u);
  EXPECT_EQ(tio.c_iflag & (IXON | IXOFF | ICRNL | INLCR | ISTRIP), 0u);
  EXPECT_EQ(tio.c_oflag & OPOST, 0u);
  EXPECT_EQ(tio.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
  EXPECT_EQ(tio.c_cflag & (PARENB | CSTOPB | CRTSCTS), 0u);
  EXPECT_EQ(tio.c_cflag & (CLOCAL | CREAD), static_cast<tcflag_t>(CLOCAL | CREAD));
  EXPECT_EQ(::cfgetospeed(&tio), static_cast<speed_t>(B115200));
  EXPECT_EQ(::fcntl(port.fd(), F_GETFL) & O_NONBLOCK, O_NONBLOCK);
  EXPECT_EQ(::fcntl(port.fd(), F_GETFD) & FD_CLOEXEC, FD_CLOEXEC);
}

TEST(SerialPort, EveryByteValuePassesUnchangedBothWays) {
  Pty pty;
  SerialPort port(pty.path(), 921600);
  const std::vector<std::uint8_t> bytes = all_bytes();  // incl. 0x03, 0x0A, 0x0D, 0x11, 0x13

  // master -> port
  ASSERT_EQ(::write(pty.master(), bytes.data(), bytes.size()), 256);
  std::vector<std::uint8_t> got;
  for (int i = 0; i < 100 && got.size() < bytes.size(); ++i) {
    std::array<std::uint8_t, 300> buf{};
    const SerialIo io = port.read_some(buf, 1000 * kNsPerMs);
    ASSERT_TRUE(io.ok()) << std::strerror(io.error);
    got.insert(got.end(), buf.begin(), buf.begin() + static_cast<long>(io.bytes));
  }
  EXPECT_EQ(got, bytes);

  // port -> master
  const SerialIo w = port.write_all(bytes, 1000 * kNsPerMs);
  ASSERT_TRUE(w.ok());
  EXPECT_EQ(w.bytes, 256u);
  EXPECT_EQ(read_n(pty.master(), 256), bytes);
}

TEST(SerialPort, ReadTimesOutWithNothing) {
  Pty pty;
  SerialPort port(pty.path(), 115200);
  std::array<std::uint8_t, 16> buf{};
  const TimeNs t0 = monotonic_now_ns();
  const SerialIo io = port.read_some(buf, 30 * kNsPerMs);
  const TimeNs t1 = monotonic_now_ns();
  EXPECT_EQ(io.bytes, 0u);
  EXPECT_EQ(io.error, ETIMEDOUT);
  EXPECT_GE(t1 - t0, 30 * kNsPerMs);  // it waited the whole timeout (a lower bound only)

  const SerialIo now = port.read_some(buf, 0);  // no wait at all
  EXPECT_EQ(now.bytes, 0u);
  EXPECT_EQ(now.error, ETIMEDOUT);
}

extern "C" void on_alarm(int) {}

TEST(SerialPort, ReadRetriesEintrUntilItsTimeout) {
  Pty pty;
  SerialPort port(pty.path(), 115200);
  struct sigaction sa {};
  sa.sa_handler = on_alarm;  // no SA_RESTART: poll() returns EINTR
  struct sigaction old {};
  ASSERT_EQ(::sigaction(SIGALRM, &sa, &old), 0);
  itimerval timer{};
  timer.it_value.tv_usec = 10'000;     // first signal after 10 ms
  timer.it_interval.tv_usec = 10'000;  // then every 10 ms
  ASSERT_EQ(::setitimer(ITIMER_REAL, &timer, nullptr), 0);
  std::array<std::uint8_t, 16> buf{};
  const TimeNs t0 = monotonic_now_ns();
  const SerialIo io = port.read_some(buf, 80 * kNsPerMs);
  const TimeNs t1 = monotonic_now_ns();
  const itimerval off{};
  ::setitimer(ITIMER_REAL, &off, nullptr);
  ::sigaction(SIGALRM, &old, nullptr);
  EXPECT_EQ(io.error, ETIMEDOUT);  // not EINTR: the signals were absorbed
  EXPECT_GE(t1 - t0, 80 * kNsPerMs);
}

TEST(SerialPort, FlushInputDropsWhatArrived) {
  Pty pty;
  SerialPort port(pty.path(), 115200);
  const std::array<std::uint8_t, 3> junk{1, 2, 3};
  ASSERT_EQ(::write(pty.master(), junk.data(), junk.size()), 3);
  pollfd p{port.fd(), POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 2000), 1);
  EXPECT_EQ(port.flush(SerialFlush::kInput), 0);
  std::array<std::uint8_t, 8> buf{};
  EXPECT_EQ(port.read_some(buf, 0).error, ETIMEDOUT);
}

TEST(SerialPort, UnsupportedBaudNamesDeviceAndRate) {
  Pty pty;
  try {
    SerialPort port(pty.path(), 12345);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(pty.path()));
    EXPECT_THAT(e.what(), HasSubstr("unsupported baud rate 12345"));
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
  }
}

TEST(SerialPort, MissingDeviceNamesPathAndStrerror) {
  try {
    SerialPort port("/dev/wallar-no-such-tty", 115200);
    FAIL() << "no error";
  } catch (const SerialError& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/wallar-no-such-tty: open: No such file or directory");
  }
}

TEST(SerialPort, NotATtyIsRefused) {
  try {
    SerialPort port("/dev/null", 115200);
    FAIL() << "no error";
  } catch (const SerialError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/dev/null: tcgetattr"));
  }
}

TEST(SerialPort, BaudTableAndByteTime) {
  EXPECT_EQ(baud_to_speed(115200), std::optional<speed_t>(B115200));
  EXPECT_EQ(baud_to_speed(9600), std::optional<speed_t>(B9600));
  EXPECT_EQ(baud_to_speed(4000000), std::optional<speed_t>(B4000000));
  EXPECT_FALSE(baud_to_speed(0).has_value());
  EXPECT_FALSE(baud_to_speed(100000).has_value());
  EXPECT_EQ(serial_byte_time_ns(115200), 86806);  // 10 bits / 115200 baud, rounded up
  EXPECT_EQ(serial_byte_time_ns(1000000), 10000);
}

TEST(SerialPort, MovedFromPortIsClosedAndHarmless) {
  Pty pty;
  SerialPort a(pty.path(), 115200);
  const int fd = a.fd();
  SerialPort b(std::move(a));
  EXPECT_EQ(b.fd(), fd);
  EXPECT_EQ(a.fd(), -1);  // NOLINT(bugprone-use-after-move): the moved-from state is specified
  std::array<std::uint8_t, 4> buf{};
  EXPECT_EQ(a.read_some(buf, 0).error, EBADF);  // NOLINT(bugprone-use-after-move)
}

TEST(ByteRing, ResyncDropsAndCountsGarbage) {
  ByteRing<16> ring;
  const std::array<std::uint8_t, 6> in{0x00, 0x13, 0xAA, 0x7F, 0xBB, 0x02};
  EXPECT_EQ(ring.push(in), 6u);
  EXPECT_EQ(ring.resync([](std::uint8_t b) { return b == 0xBB; }), 4u);
  EXPECT_EQ(ring.size(), 2u);
  EXPECT_EQ(ring[0], 0xBB);
  EXPECT_EQ(ring[1], 0x02);
  EXPECT_EQ(ring.dropped_bytes(), 4u);
  // Nothing acceptable: everything goes.
  EXPECT_EQ(ring.resync([](std::uint8_t b) { return b == 0xEE; }), 2u);
  EXPECT_TRUE(ring.empty());
  EXPECT_EQ(ring.dropped_bytes(), 6u);
}

TEST(ByteRing, WrapsAroundAndCountsOverflow) {
  ByteRing<8> ring;
  std::array<std::uint8_t, 6> a{1, 2, 3, 4, 5, 6};
  ring.push(a);
  ring.consume(5);  // parsed, not dropped
  EXPECT_EQ(ring.dropped_bytes(), 0u);
  std::array<std::uint8_t, 10> b{10, 11, 12, 13, 14, 15, 16, 17, 18, 19};
  EXPECT_EQ(ring.push(b), 7u);  // 1 left + 7 = capacity 8
  EXPECT_EQ(ring.overflow_bytes(), 3u);
  std::array<std::uint8_t, 8> out{};
  ring.copy_out(0, out);
  EXPECT_EQ(out, (std::array<std::uint8_t, 8>{6, 10, 11, 12, 13, 14, 15, 16}));
  EXPECT_EQ(ring.drop_all(), 8u);
  EXPECT_EQ(ring.dropped_bytes(), 8u);
}

}  // namespace
}  // namespace wallar::drivers
