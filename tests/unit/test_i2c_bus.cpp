// SPDX-License-Identifier: Apache-2.0
/// @file test_i2c_bus.cpp
/// @brief I2cBus builds what the kernel wants and retries what is worth retrying; GPIO open
/// errors name chip and line; timestamp conversion and debouncing as pure functions.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/drivers/bus/gpio.hpp"
#include "wallar/drivers/bus/i2c.hpp"

namespace wallar::test {
namespace {

using drivers::I2cBus;

// Answers each I2C_RDWR with the next scripted result and keeps a copy of what it got.
class ScriptedAdapter final : public drivers::I2cAdapter {
 public:
  struct Seen {
    std::vector<i2c_msg> msgs;
    std::vector<std::vector<std::uint8_t>> write_bytes;
  };
  int rdwr(i2c_rdwr_ioctl_data& data) override {
    Seen s;
    for (std::uint32_t i = 0; i < data.nmsgs; ++i) {
      s.msgs.push_back(data.msgs[i]);
      if ((data.msgs[i].flags & I2C_M_RD) == 0) {
        s.write_bytes.emplace_back(data.msgs[i].buf, data.msgs[i].buf + data.msgs[i].len);
      } else {
        for (std::uint16_t b = 0; b < data.msgs[i].len; ++b) {
          data.msgs[i].buf[b] = static_cast<std::uint8_t>(0xA0 + b);
        }
        if (shorten) data.msgs[i].len = static_cast<std::uint16_t>(data.msgs[i].len - 1);
      }
    }
    seen.push_back(s);
    if (script.empty()) return static_cast<int>(data.nmsgs);
    const int r = script.front();
    script.erase(script.begin());
    return r == kAll ? static_cast<int>(data.nmsgs) : r;
  }
  static constexpr int kAll = 1000;
  std::vector<int> script;  // negative errno, a message count, or kAll
  std::vector<Seen> seen;
  bool shorten = false;
};

TEST(I2cBus, WriteThenReadIsOneCombinedTransaction) {
  ScriptedAdapter adapter;
  I2cBus bus(adapter, 0x68);
  const std::array<std::uint8_t, 1> tx{0x72};
  std::array<std::uint8_t, 4> rx{};
  ASSERT_EQ(bus.transfer(tx, rx), 0);
  ASSERT_EQ(adapter.seen.size(), 1u);
  const auto& m = adapter.seen[0].msgs;
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].addr, 0x68);
  EXPECT_EQ(m[0].flags, 0);
  EXPECT_EQ(m[0].len, 1);
  EXPECT_EQ(m[0].buf, tx.data());
  EXPECT_EQ(m[1].addr, 0x68);
  EXPECT_EQ(m[1].flags, I2C_M_RD);
  EXPECT_EQ(m[1].len, 4);
  EXPECT_EQ(m[1].buf, rx.data());
  EXPECT_EQ(adapter.seen[0].write_bytes[0], std::vector<std::uint8_t>{0x72});
  EXPECT_EQ(rx[3], 0xA3);
}

TEST(I2cBus, WriteOnlyAndReadOnlyAreOneMessage) {
  ScriptedAdapter adapter;
  I2cBus bus(adapter, 0x0C);
  const std::array<std::uint8_t, 2> tx{0x31, 0x08};
  ASSERT_EQ(bus.transfer(tx, {}), 0);
  std::array<std::uint8_t, 2> rx{};
  ASSERT_EQ(bus.transfer({}, rx), 0);
  ASSERT_EQ(adapter.seen.size(), 2u);
  ASSERT_EQ(adapter.seen[0].msgs.size(), 1u);
  EXPECT_EQ(adapter.seen[0].msgs[0].flags, 0);
  EXPECT_EQ(adapter.seen[0].write_bytes[0], (std::vector<std::uint8_t>{0x31, 0x08}));
  ASSERT_EQ(adapter.seen[1].msgs.size(), 1u);
  EXPECT_EQ(adapter.seen[1].msgs[0].flags, I2C_M_RD);
  EXPECT_EQ(bus.transfer({}, {}), 0);  // nothing to do: nothing sent
  EXPECT_EQ(adapter.seen.size(), 2u);
}

TEST(I2cBus, EintrIsRetriedTransparently) {
  ScriptedAdapter adapter;
  adapter.script = {-EINTR, -EINTR, ScriptedAdapter::kAll};
  I2cBus bus(adapter, 0x68);
  std::array<std::uint8_t, 1> rx{};
  const std::array<std::uint8_t, 1> tx{0x00};
  EXPECT_EQ(bus.transfer(tx, rx), 0);
  EXPECT_EQ(adapter.seen.size(), 3u);
  EXPECT_EQ(bus.counters().eintr, 2u);
  EXPECT_EQ(bus.counters().failures, 0u);
}

TEST(I2cBus, BusErrorsAreRetriedABoundedNumberOfTimes) {
  for (int err : {EIO, EAGAIN, ETIMEDOUT}) {
    ScriptedAdapter adapter;
    adapter.script = {-err, -err, -err, -err};
    I2cBus bus(adapter, 0x68, I2cBus::Options{.max_retries = 2});
    const std::array<std::uint8_t, 1> tx{0x00};
    EXPECT_EQ(bus.transfer(tx, {}), err);
    EXPECT_EQ(adapter.seen.size(), 3u) << err;  // 1 + 2 retries
    EXPECT_EQ(bus.counters().retries, 2u);
    EXPECT_EQ(bus.counters().failures, 1u);
    // One error then success: the caller sees success.
    adapter.script = {-err};
    EXPECT_EQ(bus.transfer(tx, {}), 0);
  }
}

TEST(I2cBus, NacksAreNotRetried) {
  for (int err : {ENXIO, EREMOTEIO}) {
    ScriptedAdapter adapter;
    adapter.script = {-err};
    I2cBus bus(adapter, 0x68);
    const std::array<std::uint8_t, 1> tx{0x00};
    EXPECT_EQ(bus.transfer(tx, {}), err);
    EXPECT_TRUE(drivers::is_i2c_nack(err));
    EXPECT_EQ(adapter.seen.size(), 1u);
    EXPECT_EQ(bus.counters().retries, 0u);
  }
  EXPECT_FALSE(drivers::is_i2c_nack(EIO));
}

TEST(I2cBus, ShortTransfersAreReported) {
  ScriptedAdapter adapter;
  I2cBus bus(adapter, 0x68);
  const std::array<std::uint8_t, 1> tx{0x72};
  std::array<std::uint8_t, 12> rx{};
  adapter.script = {1};  // the adapter did only the first message
  EXPECT_EQ(bus.transfer(tx, rx), drivers::kI2cShortTransfer);
  adapter.shorten = true;  // the adapter read fewer bytes than asked
  EXPECT_EQ(bus.transfer(tx, rx), drivers::kI2cShortTransfer);
  adapter.shorten = false;
  EXPECT_EQ(bus.transfer(tx, rx), 0);
}

TEST(I2cBus, RecoveryHookAfterConsecutiveFailures) {
  ScriptedAdapter adapter;
  int recovered = 0;
  I2cBus bus(adapter, 0x68, I2cBus::Options{.max_retries = 0, .recover_after = 3},
             [&recovered] { ++recovered; });
  const std::array<std::uint8_t, 1> tx{0x00};
  adapter.script = {-EIO, -EIO, ScriptedAdapter::kAll, -EIO, -EIO};
  for (int i = 0; i < 5; ++i) bus.transfer(tx, {});
  EXPECT_EQ(recovered, 0);  // a success in between restarts the count
  adapter.script = {-EIO};
  bus.transfer(tx, {});
  EXPECT_EQ(recovered, 1);
  EXPECT_EQ(bus.counters().recoveries, 1u);
  EXPECT_EQ(bus.counters().failures, 5u);
}

TEST(I2cBus, OpenFailureNamesTheDevice) {
  try {
    drivers::LinuxI2cAdapter adapter("/dev/i2c-wallar-does-not-exist");
    FAIL() << "opened a nonexistent adapter";
  } catch (const DeviceError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("/dev/i2c-wallar-does-not-exist"), std::string::npos) << msg;
    EXPECT_NE(msg.find("No such file"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos);
  }
  // A device node that is not an I2C adapter.
  EXPECT_THROW(drivers::LinuxI2cAdapter("/dev/null"), DeviceError);
}

// An SMBus-only adapter (i2c-stub's model): 256 byte registers per chip at `address`, a
// register pointer for send/receive byte; every SMBus transaction it was asked for is kept.
class SmbusChip final : public drivers::SmbusPort, public drivers::I2cAdapter {
 public:
  explicit SmbusChip(unsigned long funcs) : funcs_(funcs) {}  // NOLINT(google-runtime-int)
  int smbus(std::uint16_t address, i2c_smbus_ioctl_data& call) override {
    calls.push_back({call.read_write, call.command, call.size});
    if (address != kAddress) return -ENODEV;  // what i2c-stub says for an absent chip
    if (call.read_write == I2C_SMBUS_WRITE) {
      switch (call.size) {
        case I2C_SMBUS_BYTE:
          pointer = call.command;
          return 0;
        case I2C_SMBUS_BYTE_DATA:
          regs[call.command] = call.data->byte;
          return 0;
        case I2C_SMBUS_I2C_BLOCK_DATA:
          for (int i = 0; i < call.data->block[0]; ++i) {
            regs[(call.command + i) & 0xFF] = call.data->block[1 + i];
          }
          return 0;
        default:
          return -EOPNOTSUPP;
      }
    }
    switch (call.size) {
      case I2C_SMBUS_BYTE:
        call.data->byte = regs[pointer++ & 0xFF];
        return 0;
      case I2C_SMBUS_BYTE_DATA:
        call.data->byte = regs[call.command];
        return 0;
      case I2C_SMBUS_I2C_BLOCK_DATA:
        for (int i = 0; i < call.data->block[0] && i < truncate_block_to; ++i) {
          call.data->block[1 + i] = regs[(call.command + i) & 0xFF];
        }
        call.data->block[0] =
            static_cast<std::uint8_t>(std::min<int>(call.data->block[0], truncate_block_to));
        return 0;
      default:
        return -EOPNOTSUPP;
    }
  }
  int rdwr(i2c_rdwr_ioctl_data& data) override {
    return drivers::rdwr_over_smbus(data, funcs_, *this);
  }
  struct Call {
    int read_write;
    int command;
    std::uint32_t size;
    bool operator==(const Call&) const = default;
  };
  static constexpr std::uint16_t kAddress = 0x68;
  std::array<std::uint8_t, 256> regs{};
  std::uint8_t pointer = 0;
  int truncate_block_to = 1000;
  std::vector<Call> calls;

 private:
  unsigned long funcs_;  // NOLINT(google-runtime-int)
};

constexpr unsigned long kStubFuncs =  // NOLINT(google-runtime-int): i2c-stub's default
    I2C_FUNC_SMBUS_QUICK | I2C_FUNC_SMBUS_BYTE | I2C_FUNC_SMBUS_BYTE_DATA |
    I2C_FUNC_SMBUS_WORD_DATA | I2C_FUNC_SMBUS_I2C_BLOCK;

TEST(I2cOverSmbus, EachRegisterTransferIsTheSmbusTransactionOfItsShape) {
  SmbusChip chip(kStubFuncs);
  I2cBus bus(chip, SmbusChip::kAddress);
  using C = SmbusChip::Call;
  // write byte data, then read byte data
  ASSERT_EQ(bus.transfer(std::array<std::uint8_t, 2>{0x06, 0x41}, {}), 0);
  std::array<std::uint8_t, 1> one{};
  ASSERT_EQ(bus.transfer(std::array<std::uint8_t, 1>{0x06}, one), 0);
  EXPECT_EQ(one[0], 0x41);
  // a 32-byte register write and read (I2C block), bytes in order
  std::array<std::uint8_t, 33> block_write{};
  block_write[0] = 0x20;
  for (int i = 1; i < 33; ++i) block_write[i] = static_cast<std::uint8_t>(0x80 + i);
  ASSERT_EQ(bus.transfer(block_write, {}), 0);
  std::array<std::uint8_t, 32> block{};
  ASSERT_EQ(bus.transfer(std::array<std::uint8_t, 1>{0x20}, block), 0);
  for (int i = 0; i < 32; ++i) EXPECT_EQ(block[i], 0x81 + i) << i;
  // send byte sets the pointer, receive byte reads there
  ASSERT_EQ(bus.transfer(std::array<std::uint8_t, 1>{0x06}, {}), 0);
  ASSERT_EQ(bus.transfer({}, one), 0);
  EXPECT_EQ(one[0], 0x41);
  const std::vector<C> want{{I2C_SMBUS_WRITE, 0x06, I2C_SMBUS_BYTE_DATA},
                            {I2C_SMBUS_READ, 0x06, I2C_SMBUS_BYTE_DATA},
                            {I2C_SMBUS_WRITE, 0x20, I2C_SMBUS_I2C_BLOCK_DATA},
                            {I2C_SMBUS_READ, 0x20, I2C_SMBUS_I2C_BLOCK_DATA},
                            {I2C_SMBUS_WRITE, 0x06, I2C_SMBUS_BYTE},
                            {I2C_SMBUS_READ, 0, I2C_SMBUS_BYTE}};
  EXPECT_EQ(chip.calls, want);
  EXPECT_EQ(bus.counters().failures, 0u);
}

TEST(I2cOverSmbus, WhatSmbusCannotCarryIsRefusedNotSplit) {
  SmbusChip chip(kStubFuncs);
  I2cBus bus(chip, SmbusChip::kAddress);
  std::array<std::uint8_t, 33> too_long{};
  // 33 bytes from a register: two block reads would mean something else to a FIFO register
  // than to a run of registers, so the adapter does not guess.
  EXPECT_EQ(bus.transfer(std::array<std::uint8_t, 1>{0x00}, too_long), EOPNOTSUPP);
  std::array<std::uint8_t, 34> long_write{};
  EXPECT_EQ(bus.transfer(long_write, {}), EOPNOTSUPP);
  std::array<std::uint8_t, 2> two{};
  EXPECT_EQ(bus.transfer(std::array<std::uint8_t, 2>{0x00, 0x01}, two), EOPNOTSUPP);  // 2-byte reg
  EXPECT_EQ(bus.transfer({}, two), EOPNOTSUPP);  // a bare 2-byte read
  EXPECT_TRUE(chip.calls.empty()) << "nothing half-done on the bus";
  // Without I2C-block support, a multi-byte register read is refused; byte data still works.
  SmbusChip byte_only(I2C_FUNC_SMBUS_BYTE_DATA);
  I2cBus byte_bus(byte_only, SmbusChip::kAddress);
  std::array<std::uint8_t, 6> six{};
  EXPECT_EQ(byte_bus.transfer(std::array<std::uint8_t, 1>{0x2D}, six), EOPNOTSUPP);
  std::array<std::uint8_t, 1> one{};
  EXPECT_EQ(byte_bus.transfer(std::array<std::uint8_t, 1>{0x2D}, one), 0);
  EXPECT_EQ(byte_bus.transfer(std::array<std::uint8_t, 1>{0x2D}, {}), EOPNOTSUPP);  // no send byte
}

TEST(I2cOverSmbus, AShortBlockAndAnAbsentChipAreErrors) {
  SmbusChip chip(kStubFuncs);
  I2cBus bus(chip, SmbusChip::kAddress);
  chip.truncate_block_to = 5;
  std::array<std::uint8_t, 12> rx{};
  EXPECT_EQ(bus.transfer(std::array<std::uint8_t, 1>{0x2D}, rx), drivers::kI2cShortTransfer);
  I2cBus absent(chip, 0x69);
  std::array<std::uint8_t, 1> one{};
  EXPECT_EQ(absent.transfer(std::array<std::uint8_t, 1>{0x00}, one), ENODEV);
  EXPECT_EQ(absent.counters().retries, 0u);
}

TEST(Gpio, OpenFailureNamesChipAndLine) {
  const drivers::GpioLineSpec spec{"gpiochip-wallar-none", 24, false};
  try {
    drivers::GpioEdgeInput input(spec, "wallar-test");
    FAIL() << "opened a nonexistent chip";
  } catch (const DeviceError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("gpiochip-wallar-none line 24"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos);
  }
  EXPECT_THROW(drivers::GpioButton(spec, "wallar-test", 20 * kNsPerMs), DeviceError);
  EXPECT_THROW(drivers::GpioOutput(spec, "wallar-test"), DeviceError);
}

TEST(Gpio, KernelTimestampToNanoseconds) {
  EXPECT_EQ(drivers::timespec_to_ns(timespec{1, 5}), 1'000'000'005);
  EXPECT_EQ(drivers::timespec_to_ns(timespec{0, 0}), 0);
  EXPECT_EQ(drivers::timespec_to_ns(timespec{1'700'000'000, 999'999'999}),
            1'700'000'000'999'999'999);
  static_assert(drivers::timespec_to_ns(timespec{2, 1}) == 2'000'000'001);
}

TEST(Gpio, DebounceIgnoresBounceAndReportsTheFirstChangeAtOnce) {
  drivers::Debouncer d(20 * kNsPerMs, false);
  EXPECT_EQ(d.on_edge(true, 100 * kNsPerMs), std::optional<bool>(true));  // no added latency
  EXPECT_FALSE(d.on_edge(false, 101 * kNsPerMs));                         // bounce
  EXPECT_FALSE(d.on_edge(true, 102 * kNsPerMs));
  EXPECT_FALSE(d.settle(130 * kNsPerMs));  // settled where it was reported
  EXPECT_FALSE(d.settle_deadline());
  EXPECT_TRUE(d.level());
  // Release with bounce, well after the window.
  EXPECT_EQ(d.on_edge(false, 300 * kNsPerMs), std::optional<bool>(false));
  EXPECT_FALSE(d.on_edge(true, 301 * kNsPerMs));
  EXPECT_FALSE(d.on_edge(false, 303 * kNsPerMs));
  EXPECT_FALSE(d.level());
}

TEST(Gpio, DebounceDoesNotLoseAShortPressRelease) {
  drivers::Debouncer d(20 * kNsPerMs, false);
  EXPECT_EQ(d.on_edge(true, 0), std::optional<bool>(true));
  EXPECT_FALSE(d.on_edge(false, 5 * kNsPerMs));  // released inside the window
  ASSERT_TRUE(d.settle_deadline());
  EXPECT_EQ(*d.settle_deadline(), 25 * kNsPerMs);
  EXPECT_FALSE(d.settle(24 * kNsPerMs));
  EXPECT_EQ(d.settle(25 * kNsPerMs), std::optional<bool>(false));
  EXPECT_FALSE(d.level());
}

}  // namespace
}  // namespace wallar::test
