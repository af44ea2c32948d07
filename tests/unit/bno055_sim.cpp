// SPDX-License-Identifier: Apache-2.0
/// @file bno055_sim.cpp
/// @brief The pseudo-terminal BNO055: request parsing and chip-like answers.
#include "bno055_sim.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace wallar::test {
namespace {

using drivers::bno055::Reg;
using drivers::bno055::reg_addr;

void put_i16(std::array<std::uint8_t, 0x80>& regs, std::uint8_t addr, std::int16_t v) {
  const auto u = static_cast<std::uint16_t>(v);
  regs[addr] = static_cast<std::uint8_t>(u & 0xFF);
  regs[addr + 1] = static_cast<std::uint8_t>((u >> 8) & 0xFF);
}

}  // namespace

drivers::bno055::RawBurst bno055_motion(std::uint32_t n) {
  drivers::bno055::RawBurst r;
  // A slow yaw: 0.5 rad/s about z, sampled at 100 Hz; small wobble on x/y; gravity on z.
  const double yaw = 0.005 * n;
  r.acc = {static_cast<std::int16_t>(n & 0x7FFF), static_cast<std::int16_t>(-12 + (n % 7)), 981};
  r.gyr = {static_cast<std::int16_t>((n % 11) - 5), -3, 450};  // 450 LSB = 0.5 rad/s
  r.mag = {static_cast<std::int16_t>(std::lround(400.0 * std::cos(yaw))),
           static_cast<std::int16_t>(std::lround(-400.0 * std::sin(yaw))), -640};
  r.qua = {static_cast<std::int16_t>(std::lround(16384.0 * std::cos(yaw / 2))), 0, 0,
           static_cast<std::int16_t>(std::lround(16384.0 * std::sin(yaw / 2)))};
  r.temp = static_cast<std::int8_t>(24 + (n % 3));
  return r;
}

Bno055Sim::Bno055Sim(int fd, Motion motion)
    : master_(fd), owns_fds_(false), motion_(std::move(motion)) {
  ::fcntl(master_, F_SETFL, ::fcntl(master_, F_GETFL) | O_NONBLOCK);
  reset_registers();
}

Bno055Sim::Bno055Sim()
    : motion_([](std::uint64_t n, TimeNs /*now_ns*/) {
        return bno055_motion(static_cast<std::uint32_t>(n));
      }) {
  char name[128] = {};
  if (::openpty(&master_, &slave_, name, nullptr, nullptr) != 0) {
    throw std::runtime_error("openpty failed");
  }
  slave_path_ = name;
  termios tio{};
  ::tcgetattr(slave_, &tio);
  ::cfmakeraw(&tio);  // no echo of what the sim writes before the driver sets raw itself
  ::tcsetattr(slave_, TCSANOW, &tio);
  ::fcntl(master_, F_SETFL, ::fcntl(master_, F_GETFL) | O_NONBLOCK);
  reset_registers();
}

Bno055Sim::~Bno055Sim() {
  if (!owns_fds_) return;
  ::close(master_);
  ::close(slave_);  // held open so the master never sees a hang-up between driver opens
}

void Bno055Sim::reset_registers() {
  regs.fill(0);
  regs[reg_addr(Reg::kChipId)] = chip_id;
  regs[reg_addr(Reg::kAccId)] = 0xFB;
  regs[reg_addr(Reg::kMagId)] = 0x32;
  regs[reg_addr(Reg::kGyrId)] = 0x0F;
  regs[reg_addr(Reg::kUnitSel)] = 0x80;  // datasheet reset value: Android orientation
  regs[reg_addr(Reg::kOprMode)] = 0x00;  // CONFIG
  regs[reg_addr(Reg::kPwrMode)] = 0x00;
}

void Bno055Sim::send(const std::vector<std::uint8_t>& bytes) {
  out_.insert(out_.end(), bytes.begin(), bytes.end());
}

void Bno055Sim::answer_burst(std::uint8_t reg, std::uint8_t len, TimeNs now_ns) {
  if (ignore_next > 0) {
    --ignore_next;
    return;
  }
  if (status_next_count > 0) {
    --status_next_count;
    send({0xEE, status_next});
    return;
  }
  const drivers::bno055::RawBurst m = motion_(bursts_served, now_ns);
  for (int i = 0; i < 3; ++i) {
    put_i16(regs, static_cast<std::uint8_t>(0x08 + 2 * i), m.acc[i]);
    put_i16(regs, static_cast<std::uint8_t>(0x0E + 2 * i), m.mag[i]);
    put_i16(regs, static_cast<std::uint8_t>(0x14 + 2 * i), m.gyr[i]);
  }
  for (int i = 0; i < 4; ++i) put_i16(regs, static_cast<std::uint8_t>(0x20 + 2 * i), m.qua[i]);
  regs[reg_addr(Reg::kTemp)] = static_cast<std::uint8_t>(m.temp);
  ++bursts_served;

  std::vector<std::uint8_t> frame;
  for (std::size_t i = 0; i < garbage_next; ++i) {
    frame.push_back(static_cast<std::uint8_t>((0x11 + 37 * i) % 0xB0));  // < 0xBB: never a start
  }
  garbage_next = 0;
  frame.push_back(0xBB);
  frame.push_back(static_cast<std::uint8_t>(len + wrong_length_next));
  wrong_length_next = 0;
  for (std::size_t i = 0; i < len; ++i) frame.push_back(regs[(reg + i) & 0x7F]);
  if (split_next) {
    split_next = false;
    const std::size_t half = frame.size() / 2;
    send(std::vector<std::uint8_t>(frame.begin(), frame.begin() + static_cast<long>(half)));
    deferred_.assign(frame.begin() + static_cast<long>(half), frame.end());
    return;
  }
  send(frame);
}

void Bno055Sim::handle(const std::uint8_t* req, std::size_t len, TimeNs now_ns, bool write) {
  ++requests_seen;
  if (silent || now_ns < boot_until_ns_) return;  // unplugged, or booting: no answer
  const std::uint8_t reg = req[2];
  const std::uint8_t n = req[3];
  if (write) {
    ++writes_seen;
    if (reg == reg_addr(Reg::kSysTrigger) && (req[4] & (1u << 5)) != 0) {
      send({0xEE, 0x01});  // acked, then the chip reboots
      ++resets_seen;
      reset_registers();
      boot_until_ns_ = now_ns + boot_ns;
      return;
    }
    for (std::size_t i = 0; i < n && 4 + i < len; ++i) regs[(reg + i) & 0x7F] = req[4 + i];
    send({0xEE, 0x01});
    return;
  }
  if (reg == reg_addr(Reg::kAccDataXLsb) && n == drivers::bno055::kBurstBytes) {
    answer_burst(reg, n, now_ns);
    return;
  }
  std::vector<std::uint8_t> frame{0xBB, n};
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t a = (reg + i) & 0x7F;
    frame.push_back(a == reg_addr(Reg::kChipId) ? chip_id : regs[a]);
  }
  send(frame);
}

std::size_t Bno055Sim::pump(TimeNs now_ns, std::uint64_t requests_expected) {
  out_ = std::move(deferred_);
  deferred_.clear();
  for (int waits = 0;; ++waits) {
    std::array<std::uint8_t, 256> buf{};
    for (;;) {
      const ssize_t got = ::read(master_, buf.data(), buf.size());
      if (got <= 0) break;
      rx_.insert(rx_.end(), buf.begin(), buf.begin() + got);
    }
    // Complete requests: 0xAA 0x01 reg len | 0xAA 0x00 reg len data[len].
    std::size_t pos = 0;
    while (pos < rx_.size()) {
      if (rx_[pos] != 0xAA) {
        ++pos;  // the chip would answer WRONG_START_BYTE; the driver never sends this
        continue;
      }
      if (rx_.size() - pos < 4) break;
      const bool write = rx_[pos + 1] == 0x00;
      const std::size_t need = write ? 4u + rx_[pos + 3] : 4u;
      if (rx_.size() - pos < need) break;
      handle(rx_.data() + pos, need, now_ns, write);
      pos += need;
    }
    rx_.erase(rx_.begin(), rx_.begin() + static_cast<long>(pos));
    if (requests_seen >= requests_expected || waits >= 20) break;
    pollfd p{master_, POLLIN, 0};
    if (::poll(&p, 1, 2000) <= 0) break;  // the request never came: the test will say so
  }
  std::size_t written = 0;
  while (written < out_.size()) {
    const ssize_t w = ::write(master_, out_.data() + written, out_.size() - written);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) break;
    written += static_cast<std::size_t>(w);
  }
  return written;
}

}  // namespace wallar::test
