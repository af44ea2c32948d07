// SPDX-License-Identifier: Apache-2.0
/// @file i2c_stub_check.cpp
/// @brief The guest side of `tools/kernel-test i2c-stub`: the product's I2C bus code and its
/// ICM-20948 driver against Linux's i2c-stub (a real kernel SMBus adapter through i2c-dev),
/// booted under qemu-system-x86_64 as the initramfs's init. Never part of the product.
///
///   wallar_i2c_stub_check            (as PID 1: mounts /dev, /proc, /sys, loads /modules)
///
/// The host loads i2c-stub with one chip at 0x68 banked the way the ICM-20948 banks its
/// registers (REG_BANK_SEL 0x7F, bits [5:4], registers 0x00-0x7E in every bank): modprobe
/// i2c-stub chip_addr=0x68 bank_reg=0x7f bank_mask=0x30 bank_start=0x00 bank_end=0x7e.
/// i2c-stub is SMBus only (no I2C_RDWR), so every transfer goes through the bus code's SMBus
/// path (rdwr_over_smbus). Checks, one line each ("ok   ..." / "FAIL ..."), then "exit N":
///   - the adapter is found by its sysfs name and opened in SMBus mode;
///   - byte and 32-byte register round trips, a 33-byte read refused (EOPNOTSUPP) and an
///     absent chip an error that is not retried;
///   - bank-2 storage apart from bank 0 (the stub's banks, selected by the bus code's writes);
///   - the ICM-20948 driver from RESET to RUN with no transfer failure: the check plays only
///     the chip's reset (WHO_AM_I and PWR_MGMT_1 back at their reset values after the driver's
///     DEVICE_RESET, as the chip does in 100 us), everything else is the stub's memory, and the
///     configured rate divider is read back in bank 2 with WHO_AM_I intact in bank 0;
///   - a FIFO_COUNT of 60 bytes (written into the stub) read as whole-record I2C block reads
///     of at most 32 bytes: five samples, no failed transfer.
/// What i2c-stub cannot show: a FIFO, data-ready edges, clock stretching, a NACK mid-transfer
/// (docs/boot.md).
/// As PID 1 it powers the machine off at the end (reboot(RB_POWER_OFF)).
#include <fcntl.h>
#include <sys/mount.h>
#include <sys/reboot.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>

#include "wallar/drivers/bus/i2c.hpp"
#include "wallar/drivers/imu/icm20948.hpp"
#include "wallar/drivers/imu/icm20948_registers.hpp"

namespace {

using wallar::drivers::I2cBus;
namespace icm = wallar::drivers::icm20948;

int failures = 0;

void check(bool ok, const std::string& what) {
  std::printf("%s %s\n", ok ? "ok  " : "FAIL", what.c_str());
  std::fflush(stdout);
  if (!ok) ++failures;
}

std::int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// PID 1's chores: the file systems, then each "/path/to/module.ko [params]" line of /modules.
void init_system() {
  ::mount("devtmpfs", "/dev", "devtmpfs", 0, nullptr);
  ::mount("proc", "/proc", "proc", 0, nullptr);
  ::mount("sysfs", "/sys", "sysfs", 0, nullptr);
  std::ifstream modules("/modules");
  std::string line;
  while (std::getline(modules, line)) {
    std::istringstream words(line);
    std::string path;
    std::string params;
    words >> path;
    std::getline(words >> std::ws, params);
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    const long r = fd < 0 ? -1 : ::syscall(SYS_finit_module, fd, params.c_str(), 0);  // NOLINT
    const int err = errno;
    if (fd >= 0) ::close(fd);
    check(r == 0 || err == EEXIST, "module " + path + (params.empty() ? "" : " " + params) +
                                       (r == 0 ? "" : std::string(": ") + std::strerror(err)));
  }
}

// The i2c-dev node of the adapter named `name` in sysfs.
std::optional<std::string> find_adapter(const std::string& name) {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/sys/class/i2c-dev", ec)) {
    std::ifstream f(entry.path() / "name");
    std::string got;
    std::getline(f, got);
    if (got == name) return "/dev/" + entry.path().filename().string();
  }
  return std::nullopt;
}

int write_reg(I2cBus& bus, std::uint8_t reg, std::uint8_t value) {
  const std::array<std::uint8_t, 2> tx{reg, value};
  return bus.transfer(tx, {});
}

int read_reg(I2cBus& bus, std::uint8_t reg, std::uint8_t& value) {
  const std::array<std::uint8_t, 1> tx{reg};
  std::array<std::uint8_t, 1> rx{};
  const int err = bus.transfer(tx, rx);
  value = rx[0];
  return err;
}

std::string hex(unsigned v) {
  char b[8];
  std::snprintf(b, sizeof b, "0x%02x", v);
  return b;
}

class CountingSink final : public wallar::drivers::ImuSampleSink {
 public:
  void on_imu_sample(const wallar::ImuSample& /*sample*/) noexcept override { ++samples; }
  std::uint64_t samples = 0;
};

void run_checks() {
  const auto node = find_adapter("SMBus stub driver");
  check(node.has_value(), "i2c-stub's adapter in /sys/class/i2c-dev" +
                              (node ? " (" + *node + ")" : std::string(": not found")));
  if (!node) return;
  wallar::drivers::LinuxI2cAdapter adapter(*node);
  check(adapter.smbus_only(), "the adapter opens in SMBus mode (no I2C_FUNC_I2C)");
  constexpr std::uint16_t kChip = 0x68;
  I2cBus bus(adapter, kChip);

  // Bank 0 (the stub starts there): a byte, then 32 bytes, each written and read back.
  std::uint8_t v = 0;
  const bool byte_ok = write_reg(bus, icm::kRegBankSel, 0x00) == 0 &&
                       write_reg(bus, 0x10, 0x5A) == 0 && read_reg(bus, 0x10, v) == 0;
  check(byte_ok && v == 0x5A, "byte register write and read back (" + hex(v) + ")");
  std::array<std::uint8_t, 33> block_tx{};
  block_tx[0] = 0x40;
  for (std::size_t i = 1; i < block_tx.size(); ++i) block_tx[i] = static_cast<std::uint8_t>(3 * i);
  std::array<std::uint8_t, 32> block_rx{};
  const std::array<std::uint8_t, 1> at40{0x40};
  const int wr = bus.transfer(block_tx, {});
  const int rd = bus.transfer(at40, block_rx);
  check(wr == 0 && rd == 0 && std::memcmp(block_rx.data(), &block_tx[1], 32) == 0,
        "32-byte register write and read back (I2C block)");
  std::array<std::uint8_t, 33> too_long{};
  const auto before = bus.counters();
  const int refused = bus.transfer(at40, too_long);
  check(refused == EOPNOTSUPP, std::string("a 33-byte read is refused: ") + std::strerror(refused));
  I2cBus absent(adapter, 0x69);
  const int nobody = read_reg(absent, 0x00, v);
  check(nobody != 0 && absent.counters().retries == 0,
        std::string("an absent chip (0x69) is an error, not retried: ") + std::strerror(nobody));
  check(bus.counters().retries == before.retries, "no retries on the stub");

  // Banks: bank 2's register 0x01 is not bank 0's.
  std::uint8_t b0 = 0;
  std::uint8_t b2 = 0;
  const bool banks_ok =
      write_reg(bus, 0x01, 0x11) == 0 && write_reg(bus, icm::kRegBankSel, 0x20) == 0 &&
      write_reg(bus, 0x01, 0x22) == 0 && write_reg(bus, icm::kRegBankSel, 0x00) == 0 &&
      read_reg(bus, 0x01, b0) == 0 && write_reg(bus, icm::kRegBankSel, 0x20) == 0 &&
      read_reg(bus, 0x01, b2) == 0 && write_reg(bus, icm::kRegBankSel, 0x00) == 0;
  check(banks_ok && b0 == 0x11 && b2 == 0x22,
        "bank 2 apart from bank 0 (register 0x01: " + hex(b0) + " / " + hex(b2) + ")");

  // The ICM-20948 driver from RESET to RUN over the stub.
  wallar::drivers::Icm20948::Config config;
  config.rate_hz = 100.0;
  config.mag_enabled = false;  // the AK09916 sits behind the chip's own I2C master
  config.has_data_ready = false;
  CountingSink sink;
  wallar::drivers::Icm20948 driver(bus, config, sink);
  auto state = driver.state();
  const std::int64_t start_ns = now_ns();
  int resets_played = 0;
  while (now_ns() - start_ns < 2'000'000'000) {
    const auto previous = state;
    const std::int64_t next_ns = driver.step(now_ns(), std::nullopt);
    state = driver.state();
    if (previous == wallar::drivers::ImuDriverState::kReset &&
        state == wallar::drivers::ImuDriverState::kWaitForReset) {
      // The chip's reset: registers back at their reset values, bank 0 selected.
      ++resets_played;
      write_reg(bus, icm::kRegBankSel, 0x00);
      write_reg(bus, static_cast<std::uint8_t>(icm::Reg0::WHO_AM_I), icm::kWhoAmIValue);
      write_reg(bus, static_cast<std::uint8_t>(icm::Reg0::PWR_MGMT_1), icm::kPwrMgmt1ResetValue);
    }
    if (state == wallar::drivers::ImuDriverState::kRun && now_ns() - start_ns > 300'000'000) break;
    const std::int64_t wait_ns = next_ns - now_ns();
    if (wait_ns > 0) {
      const timespec ts{0, static_cast<long>(std::min<std::int64_t>(wait_ns, 10'000'000))};
      nanosleep(&ts, nullptr);
    }
  }
  const auto& c = driver.counters();
  check(state == wallar::drivers::ImuDriverState::kRun,
        std::string("ICM-20948 driver reaches RUN (state ") +
            std::string(wallar::drivers::to_string(state)) + ", " + std::to_string(resets_played) +
            " reset played)");
  check(c.bad_transfer == 0 && c.nack == 0 && c.short_transfer == 0 && c.config_mismatch == 0 &&
            c.resets == 0,
        "no failed transfer, mismatch or reset: " + wallar::drivers::format_counters(c));
  // Left in bank 0 by the driver or not, the register file says what it configured.
  std::uint8_t divider = 0;
  std::uint8_t who = 0;
  const bool read_ok =
      write_reg(bus, icm::kRegBankSel, icm::bank_sel_value(icm::Bank::k2)) == 0 &&
      read_reg(bus, static_cast<std::uint8_t>(icm::Reg2::GYRO_SMPLRT_DIV), divider) == 0 &&
      write_reg(bus, icm::kRegBankSel, 0x00) == 0 &&
      read_reg(bus, static_cast<std::uint8_t>(icm::Reg0::WHO_AM_I), who) == 0;
  const int want_divider = static_cast<int>(icm::kBaseRateHz / driver.rate_hz() + 0.5) - 1;
  check(read_ok && divider == want_divider && who == icm::kWhoAmIValue,
        "bank 2 GYRO_SMPLRT_DIV " + std::to_string(divider) + " (want " +
            std::to_string(want_divider) + " for " + std::to_string(driver.rate_hz()) +
            " Hz), bank 0 WHO_AM_I " + hex(who));
  check(sink.samples == 0, "no samples from an empty FIFO (" + std::to_string(sink.samples) + ")");

  // A FIFO that says it holds five records (60 bytes, more than one SMBus block): the stub's
  // FIFO_R_W is one memory cell, so each record reads as 12 copies of it, but the driver must
  // carry the burst as whole-record I2C block reads with no failed transfer.
  const auto fifo_reads_before = bus.counters().transfers;
  const bool fifo_ok =
      write_reg(bus, icm::kRegBankSel, 0x00) == 0 &&
      write_reg(bus, static_cast<std::uint8_t>(icm::Reg0::FIFO_COUNTH), 0x00) == 0 &&
      write_reg(bus, static_cast<std::uint8_t>(icm::Reg0::FIFO_COUNTL), 60) == 0 &&
      write_reg(bus, static_cast<std::uint8_t>(icm::Reg0::FIFO_R_W), 0x01) == 0;
  const std::int64_t fifo_start_ns = now_ns();
  while (fifo_ok && sink.samples < 5 && now_ns() - fifo_start_ns < 1'000'000'000) {
    const std::int64_t next_ns = driver.step(now_ns(), std::nullopt);
    const std::int64_t wait_ns = next_ns - now_ns();
    if (wait_ns > 0) {
      const timespec ts{0, static_cast<long>(std::min<std::int64_t>(wait_ns, 10'000'000))};
      nanosleep(&ts, nullptr);
    }
  }
  check(fifo_ok && sink.samples == 5 && driver.state() == wallar::drivers::ImuDriverState::kRun &&
            c.bad_transfer == 0 && c.resync == 0,
        "a 60-byte FIFO burst over SMBus blocks of " + std::to_string(bus.max_read_bytes()) +
            " bytes: " + std::to_string(sink.samples) + " samples in " +
            std::to_string(bus.counters().transfers - fifo_reads_before) + " transfers, " +
            wallar::drivers::format_counters(c));
  const auto transfers = bus.counters().transfers + absent.counters().transfers;
  const auto failed = bus.counters().failures + absent.counters().failures;
  check(failed == 2, "i2c-stub: " + std::to_string(transfers) + " transfers, " +
                         std::to_string(failed) +
                         " failed (want 2: the absent chip, the 33-byte read)");
}

}  // namespace

int main() {
  const bool init = ::getpid() == 1;
  if (init) init_system();
  try {
    run_checks();
  } catch (const std::exception& e) {
    check(false, e.what());
  }
  std::printf("exit %d\n", failures == 0 ? 0 : 1);
  std::fflush(stdout);
  if (init) {
    ::sync();
    ::reboot(RB_POWER_OFF);
  }
  return failures == 0 ? 0 : 1;
}
