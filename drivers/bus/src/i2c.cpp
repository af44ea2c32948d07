// SPDX-License-Identifier: Apache-2.0
/// @file i2c.cpp
/// @brief /dev/i2c-N through I2C_RDWR (one combined write-then-read transaction per transfer),
/// or through I2C_SMBUS on an adapter without plain I2C.
#include "wallar/drivers/bus/i2c.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <utility>

#include "wallar/core/error.hpp"

namespace wallar::drivers {

namespace {

constexpr unsigned long kSmbusRegisterFuncs =  // NOLINT(google-runtime-int)
    I2C_FUNC_SMBUS_READ_BYTE_DATA | I2C_FUNC_SMBUS_WRITE_BYTE_DATA;

}  // namespace

int rdwr_over_smbus(i2c_rdwr_ioctl_data& data, unsigned long funcs,  // NOLINT(google-runtime-int)
                    SmbusPort& port) {
  if (data.nmsgs == 0) return 0;
  if (data.nmsgs > 2) return -EOPNOTSUPP;
  i2c_msg& first = data.msgs[0];
  const bool first_reads = (first.flags & I2C_M_RD) != 0;
  i2c_msg* write = first_reads ? nullptr : &first;
  i2c_msg* read = first_reads ? &first : nullptr;
  if (data.nmsgs == 2) {
    i2c_msg& second = data.msgs[1];
    // SMBus has a write-then-read (a register read) and nothing else with two parts.
    if (first_reads || (second.flags & I2C_M_RD) == 0 || second.addr != first.addr) {
      return -EOPNOTSUPP;
    }
    read = &second;
  }
  if ((first.flags & ~static_cast<std::uint16_t>(I2C_M_RD)) != 0 ||
      (read != nullptr && (read->flags & ~static_cast<std::uint16_t>(I2C_M_RD)) != 0)) {
    return -EOPNOTSUPP;  // ten-bit addresses, no-start and the like are plain I2C only
  }
  i2c_smbus_data payload{};
  i2c_smbus_ioctl_data call{};
  call.data = &payload;
  const auto need = [&](unsigned long f) { return (funcs & f) == f; };  // NOLINT
  if (write != nullptr && read == nullptr) {
    call.read_write = I2C_SMBUS_WRITE;
    if (write->len == 0) return -EOPNOTSUPP;
    call.command = write->buf[0];
    if (write->len == 1) {
      if (!need(I2C_FUNC_SMBUS_WRITE_BYTE)) return -EOPNOTSUPP;
      call.size = I2C_SMBUS_BYTE;
      call.data = nullptr;
    } else if (write->len == 2) {
      if (!need(I2C_FUNC_SMBUS_WRITE_BYTE_DATA)) return -EOPNOTSUPP;
      call.size = I2C_SMBUS_BYTE_DATA;
      payload.byte = write->buf[1];
    } else {
      const std::size_t n = write->len - 1U;
      if (n > kSmbusBlockMax || !need(I2C_FUNC_SMBUS_WRITE_I2C_BLOCK)) return -EOPNOTSUPP;
      call.size = I2C_SMBUS_I2C_BLOCK_DATA;
      payload.block[0] = static_cast<std::uint8_t>(n);
      std::memcpy(&payload.block[1], &write->buf[1], n);
    }
    const int r = port.smbus(write->addr, call);
    return r < 0 ? r : 1;
  }
  // A read, with or without its register.
  call.read_write = I2C_SMBUS_READ;
  if (read->len == 0) return -EOPNOTSUPP;
  if (write == nullptr) {
    if (read->len != 1 || !need(I2C_FUNC_SMBUS_READ_BYTE)) return -EOPNOTSUPP;
    call.size = I2C_SMBUS_BYTE;
  } else {
    if (write->len != 1) return -EOPNOTSUPP;  // a register is one byte on SMBus
    call.command = write->buf[0];
    if (read->len == 1 && need(I2C_FUNC_SMBUS_READ_BYTE_DATA)) {
      call.size = I2C_SMBUS_BYTE_DATA;
    } else if (read->len <= kSmbusBlockMax && need(I2C_FUNC_SMBUS_READ_I2C_BLOCK)) {
      call.size = I2C_SMBUS_I2C_BLOCK_DATA;
      payload.block[0] = static_cast<std::uint8_t>(read->len);  // the length to read
    } else {
      return -EOPNOTSUPP;
    }
  }
  const int r = port.smbus(read->addr, call);
  if (r < 0) return r;
  if (call.size == I2C_SMBUS_I2C_BLOCK_DATA) {
    // The adapter says how many bytes it read in block[0]; fewer is a short transfer.
    const std::uint16_t got = std::min<std::uint16_t>(payload.block[0], read->len);
    std::memcpy(read->buf, &payload.block[1], got);
    read->len = got;
  } else {
    read->buf[0] = payload.byte;
  }
  return static_cast<int>(data.nmsgs);
}

LinuxI2cAdapter::LinuxI2cAdapter(std::string path) : path_(std::move(path)) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) {
    throw DeviceError(path_ + ": cannot open I2C adapter: " + std::strerror(errno));
  }
  if (::ioctl(fd_, I2C_FUNCS, &funcs_) < 0) {
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    throw DeviceError(path_ + ": not an I2C adapter (I2C_FUNCS): " + std::strerror(err));
  }
  if ((funcs_ & I2C_FUNC_I2C) == 0) {
    if ((funcs_ & kSmbusRegisterFuncs) != kSmbusRegisterFuncs) {
      ::close(fd_);
      fd_ = -1;
      char funcs[32];
      std::snprintf(funcs, sizeof funcs, "0x%08lx", funcs_);
      throw DeviceError(path_ + ": neither plain-I2C nor SMBus register transfers (I2C_FUNCS " +
                        funcs + ")");
    }
    smbus_only_ = true;
  }
}

LinuxI2cAdapter::~LinuxI2cAdapter() {
  if (fd_ >= 0) ::close(fd_);
}

bool LinuxI2cAdapter::reopen() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
  slave_address_ = -1;  // a new descriptor has no I2C_SLAVE address yet
  return fd_ >= 0;
}

int LinuxI2cAdapter::rdwr(i2c_rdwr_ioctl_data& data) {
  if (fd_ < 0) return -ENODEV;
  if (smbus_only_) return rdwr_over_smbus(data, funcs_, *this);
  const int n = ::ioctl(fd_, I2C_RDWR, &data);
  return n < 0 ? -errno : n;
}

std::size_t LinuxI2cAdapter::max_read_bytes() const {
  if (!smbus_only_) return kI2cNoReadLimit;
  return (funcs_ & I2C_FUNC_SMBUS_READ_I2C_BLOCK) != 0 ? kSmbusBlockMax : 1;
}

int LinuxI2cAdapter::smbus(std::uint16_t address, i2c_smbus_ioctl_data& call) {
  if (fd_ < 0) return -ENODEV;
  // i2c-dev's SMBus transactions go to the address I2C_SLAVE set (EBUSY: a kernel driver
  // has bound that address).
  if (slave_address_ != address) {
    if (::ioctl(fd_, I2C_SLAVE, static_cast<unsigned long>(address)) < 0) {  // NOLINT
      return -errno;
    }
    slave_address_ = address;
  }
  return ::ioctl(fd_, I2C_SMBUS, &call) < 0 ? -errno : 0;
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

std::size_t I2cBus::max_read_bytes() const { return adapter_.max_read_bytes(); }

int I2cBus::transfer(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) {
  return transfer_with(tx, rx, options_.max_retries);
}

int I2cBus::transfer_once(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx) {
  ++counters_.once;
  return transfer_with(tx, rx, 0);
}

int I2cBus::transfer_with(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx,
                          int retries) {
  ++counters_.transfers;
  if (tx.size() > 0xFFFF || rx.size() > 0xFFFF) return EINVAL;  // i2c_msg.len is 16 bits
  int err = attempt(tx, rx);
  for (int retry = 0; retry < retries && (err == EIO || err == EAGAIN || err == ETIMEDOUT);
       ++retry) {
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
