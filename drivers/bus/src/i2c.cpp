// SPDX-License-Identifier: Apache-2.0
/// @file i2c.cpp
/// @brief /dev/i2c-N through I2C_RDWR: one combined write-then-read transaction per transfer.
#include "wallar/drivers/bus/i2c.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <array>
#include <cstring>
#include <utility>

#include "wallar/core/error.hpp"

namespace wallar::drivers {

LinuxI2cAdapter::LinuxI2cAdapter(std::string path) : path_(std::move(path)) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) {
    throw DeviceError(path_ + ": cannot open I2C adapter: " + std::strerror(errno));
  }
  unsigned long funcs = 0;  // NOLINT(google-runtime-int): the ioctl's own type
  if (::ioctl(fd_, I2C_FUNCS, &funcs) < 0 || (funcs & I2C_FUNC_I2C) == 0) {
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    throw DeviceError(path_ + ": not a plain-I2C adapter (I2C_FUNCS): " +
                      (err != 0 ? std::strerror(err) : "I2C_FUNC_I2C missing"));
  }
}

LinuxI2cAdapter::~LinuxI2cAdapter() {
  if (fd_ >= 0) ::close(fd_);
}

int LinuxI2cAdapter::rdwr(i2c_rdwr_ioctl_data& data) {
  const int n = ::ioctl(fd_, I2C_RDWR, &data);
  return n < 0 ? -errno : n;
}

I2cBus::I2cBus(I2cAdapter& adapter, std::uint16_t address, Options options,
               I2cRecoveryHook recovery)
    : adapter_(adapter), address_(address), options_(options), recovery_(std::move(recovery)) {}

int I2cBus::attempt(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) {
  std::array<i2c_msg, 2> msgs{};
  std::uint32_t n = 0;
  if (!tx.empty()) {
    // The kernel's struct is not const-correct; it does not write a write message's buffer.
    msgs[n++] = i2c_msg{address_, 0, static_cast<std::uint16_t>(tx.size()),
                        const_cast<std::uint8_t*>(tx.data())};  // NOLINT
  }
  if (!rx.empty()) {
    msgs[n++] = i2c_msg{address_, I2C_M_RD, static_cast<std::uint16_t>(rx.size()), rx.data()};
  }
  if (n == 0) return 0;
  i2c_rdwr_ioctl_data data{msgs.data(), n};
  int r = 0;
  for (int eintr = 0;; ++eintr) {
    r = adapter_.rdwr(data);
    if (r != -EINTR || eintr >= options_.max_eintr_retries) break;
    ++counters_.eintr;
  }
  if (r < 0) return -r;
  // Fewer messages than asked, or an adapter that shortened a message: the bytes are suspect.
  if (static_cast<std::uint32_t>(r) < n) return kI2cShortTransfer;
  if (!tx.empty() && msgs[0].len != tx.size()) return kI2cShortTransfer;
  if (!rx.empty() && msgs[n - 1].len != rx.size()) return kI2cShortTransfer;
  return 0;
}

int I2cBus::transfer(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) {
  ++counters_.transfers;
  if (tx.size() > 0xFFFF || rx.size() > 0xFFFF) return EINVAL;  // i2c_msg.len is 16 bits
  int err = attempt(tx, rx);
  for (int retry = 0;
       retry < options_.max_retries && (err == EIO || err == EAGAIN || err == ETIMEDOUT); ++retry) {
    ++counters_.retries;
    err = attempt(tx, rx);
  }
  if (err == 0) {
    consecutive_failures_ = 0;
    return 0;
  }
  ++counters_.failures;
  if (++consecutive_failures_ >= options_.recover_after) {
    consecutive_failures_ = 0;
    ++counters_.recoveries;
    if (recovery_) recovery_();
  }
  return err;
}

}  // namespace wallar::drivers
