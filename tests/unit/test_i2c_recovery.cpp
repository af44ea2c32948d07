// SPDX-License-Identifier: Apache-2.0
/// @file test_i2c_recovery.cpp
/// @brief The bus clear against a slave that holds SDA low, and the recovery's unbind and bind
/// of the adapter's controller on a fake sysfs tree.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/drivers/bus/i2c_recovery.hpp"

namespace wallar::test {
namespace {
namespace fs = std::filesystem;
using drivers::I2cLines;

// A slave stopped part-way through sending a byte: it drives SDA low until it has seen
// `clocks_to_release` more SCL rising edges, then lets go. Open-drain wires: a line is low when
// anyone drives it low. Records STOP conditions (SDA rising while SCL is high).
class StuckSlave final : public I2cLines {
 public:
  explicit StuckSlave(int clocks_to_release) : remaining_(clocks_to_release) {}
  void set_scl(bool high) override {
    if (high && !scl_ && remaining_ > 0) --remaining_;  // a rising edge: one bit clocked out
    if (high && !scl_) ++clocks_;
    scl_ = high;
  }
  void set_sda(bool high) override {
    const bool before = sda();
    master_sda_ = high;
    if (scl_ && !before && sda()) ++stops_;
    if (scl_ && before && !sda()) ++starts_;
  }
  bool sda() override { return master_sda_ && remaining_ == 0; }
  void half_period() override { ++half_periods_; }

  int remaining_;
  bool scl_ = true;
  bool master_sda_ = true;
  int clocks_ = 0;
  int stops_ = 0;
  int starts_ = 0;
  int half_periods_ = 0;
};

TEST(I2cBusClear, ClocksUntilTheSlaveLetsGoThenSendsAStop) {
  for (int k = 1; k <= 9; ++k) {
    StuckSlave slave(k);
    const auto clocks = drivers::i2c_bus_clear(slave);
    ASSERT_TRUE(clocks.has_value()) << k;
    EXPECT_EQ(*clocks, k);
    EXPECT_EQ(slave.stops_, 1) << k;   // the transaction is ended
    EXPECT_EQ(slave.starts_, 0) << k;  // and no new one begun
    EXPECT_TRUE(slave.scl_);           // both lines released
    EXPECT_TRUE(slave.sda());
  }
}

TEST(I2cBusClear, AFreeBusGetsOnlyTheStopAndAStuckOneFailsAfterNineClocks) {
  StuckSlave free_bus(0);
  EXPECT_EQ(drivers::i2c_bus_clear(free_bus), 0);
  EXPECT_EQ(free_bus.clocks_, 1);  // the STOP's own SCL rise
  EXPECT_EQ(free_bus.stops_, 1);
  StuckSlave shorted(1000);
  EXPECT_FALSE(drivers::i2c_bus_clear(shorted).has_value());
  EXPECT_EQ(shorted.clocks_, 9);
  EXPECT_TRUE(shorted.scl_);  // SCL released even so
}

// RP1's I2C1 on a Pi 5 as sysfs shows it: the adapter under its controller, whose driver
// directory takes the controller's name in unbind and bind.
class FakeSysfs {
 public:
  // One tree per test and process: ctest runs the tests of this file side by side.
  FakeSysfs()
      : root_(fs::temp_directory_path() /
              ("wallar_i2c_recovery_sysfs_" +
               std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
               std::to_string(::getpid()))) {
    fs::remove_all(root_);
    const fs::path ctl = root_ / "devices/platform/axi/1000120000.pcie/1f00074000.i2c";
    fs::create_directories(ctl / "i2c-1");
    fs::create_directories(root_ / "bus/i2c/devices");
    fs::create_symlink("../../../devices/platform/axi/1000120000.pcie/1f00074000.i2c/i2c-1",
                       root_ / "bus/i2c/devices/i2c-1");
    fs::create_directories(driver());
    std::ofstream(driver() / "bind") << "";
    std::ofstream(driver() / "unbind") << "";
    fs::create_symlink("../../../../../bus/platform/drivers/i2c_designware", ctl / "driver");
  }
  ~FakeSysfs() { fs::remove_all(root_); }
  FakeSysfs(const FakeSysfs&) = delete;
  FakeSysfs& operator=(const FakeSysfs&) = delete;
  [[nodiscard]] fs::path driver() const { return root_ / "bus/platform/drivers/i2c_designware"; }
  [[nodiscard]] std::string read(const char* name) const {
    std::ifstream in(driver() / name);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  fs::path root_;
};

TEST(I2cRecovery, RebindsTheAdaptersControllerAndReopensTheNode) {
  FakeSysfs sys;
  drivers::I2cRecoveryConfig config;
  config.adapter = "/dev/i2c-1";
  config.sysfs_root = sys.root_.string();
  drivers::I2cRecovery recovery(config);
  EXPECT_EQ(recovery.controller(), "1f00074000.i2c");
  int reopened = 0;
  EXPECT_TRUE(recovery.run([&] { ++reopened; }));
  EXPECT_EQ(sys.read("unbind"), "1f00074000.i2c");
  EXPECT_EQ(sys.read("bind"), "1f00074000.i2c");
  EXPECT_EQ(reopened, 1);
  EXPECT_EQ(recovery.counters().runs, 1u);
  EXPECT_EQ(recovery.counters().rebinds, 1u);
  // The driver refuses the unbind (its file is gone): nothing is bound in its place and the
  // lines are not taken from a controller that still owns them.
  fs::remove(sys.driver() / "unbind");
  fs::remove(sys.driver() / "bind");
  std::ofstream(sys.driver() / "bind") << "";
  config.scl = drivers::GpioLineSpec{"/nonexistent/gpiochip", 3, false};
  config.sda = drivers::GpioLineSpec{"/nonexistent/gpiochip", 2, false};
  drivers::I2cRecovery with_lines(config);
  EXPECT_FALSE(with_lines.run([&] { ++reopened; }));
  EXPECT_EQ(sys.read("bind"), "");
  EXPECT_EQ(with_lines.counters().rebind_failures, 1u);
  EXPECT_EQ(with_lines.counters().clear_failures, 0u);  // never tried
  EXPECT_EQ(reopened, 2);
}

TEST(I2cRecovery, MissingPiecesAreOneLineNamingTheAdapter) {
  FakeSysfs sys;
  drivers::I2cRecoveryConfig config;
  config.adapter = "/dev/i2c-7";
  config.sysfs_root = sys.root_.string();
  try {
    drivers::I2cRecovery r(config);
    FAIL() << "no throw";
  } catch (const DeviceError& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/i2c-7: bus recovery cannot rebind: no " +
                                         (sys.root_ / "bus/i2c/devices/i2c-7").string());
  }
  config.adapter = "/dev/i2c-1";
  config.scl = drivers::GpioLineSpec{"gpiochip0", 3, false};
  EXPECT_THROW(drivers::I2cRecovery{config}, DeviceError);  // scl without sda
  // Lines alone (an i2c-gpio bus: nothing to rebind) that cannot be requested: counted.
  config.rebind = false;
  config.sda = drivers::GpioLineSpec{"/nonexistent/gpiochip", 2, false};
  config.scl = drivers::GpioLineSpec{"/nonexistent/gpiochip", 3, false};
  drivers::I2cRecovery lines_only(config);
  EXPECT_TRUE(lines_only.controller().empty());
  EXPECT_FALSE(lines_only.run());
  EXPECT_EQ(lines_only.counters().clear_failures, 1u);
}

}  // namespace
}  // namespace wallar::test
