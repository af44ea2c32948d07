// SPDX-License-Identifier: Apache-2.0
/// @file i2c_recovery.cpp
/// @brief Bus clear through GPIO lines, and the adapter's platform driver unbound and bound
/// again through sysfs around it.
#include "wallar/drivers/bus/i2c_recovery.hpp"

#include <fcntl.h>
#include <gpiod.h>
#include <unistd.h>

#include <cerrno>
#include <ctime>
#include <filesystem>
#include <system_error>
#include <utility>

#include "wallar/core/error.hpp"

namespace wallar::drivers {

namespace fs = std::filesystem;

std::optional<int> i2c_bus_clear(I2cLines& lines, int max_clocks) {
  lines.set_sda(true);
  lines.set_scl(true);
  lines.half_period();
  int clocks = 0;
  // Clock until the slave has let SDA go (it finishes the byte it was sending: at most 9).
  while (!lines.sda() && clocks < max_clocks) {
    lines.set_scl(false);
    lines.half_period();
    lines.set_scl(true);
    lines.half_period();
    ++clocks;
  }
  if (!lines.sda()) return std::nullopt;
  // STOP: SDA low while SCL is low, SCL high, then SDA high while SCL is high.
  lines.set_scl(false);
  lines.half_period();
  lines.set_sda(false);
  lines.half_period();
  lines.set_scl(true);
  lines.half_period();
  lines.set_sda(true);
  lines.half_period();
  if (!lines.sda()) return std::nullopt;
  return clocks;
}

namespace {

/// SCL and SDA as open-drain outputs, released (high) at request and at the end.
class GpioI2cLines final : public I2cLines {
 public:
  GpioI2cLines(const GpioLineSpec& scl, const GpioLineSpec& sda)
      : scl_(scl, "wallar-i2c-recovery", GPIOD_LINE_REQUEST_DIRECTION_OUTPUT,
             GPIOD_LINE_REQUEST_FLAG_OPEN_DRAIN, 1),
        sda_(sda, "wallar-i2c-recovery", GPIOD_LINE_REQUEST_DIRECTION_OUTPUT,
             GPIOD_LINE_REQUEST_FLAG_OPEN_DRAIN, 1) {}
  void set_scl(bool high) override { gpiod_line_set_value(scl_.line(), high ? 1 : 0); }
  void set_sda(bool high) override { gpiod_line_set_value(sda_.line(), high ? 1 : 0); }
  // An open-drain output reads the pad: a slave holding SDA low reads low.
  bool sda() override { return gpiod_line_get_value(sda_.line()) == 1; }
  void half_period() override {
    const timespec ts{0, 5000};
    ::nanosleep(&ts, nullptr);
  }

 private:
  GpioLineRequest scl_;
  GpioLineRequest sda_;
};

bool write_sysfs(const std::string& path, const std::string& value) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const ssize_t n = ::write(fd, value.data(), value.size());
  const bool ok = n == static_cast<ssize_t>(value.size());
  return ::close(fd) == 0 && ok;
}

}  // namespace

I2cRecovery::I2cRecovery(I2cRecoveryConfig config) : config_(std::move(config)) {
  if (config_.scl.has_value() != config_.sda.has_value()) {
    throw DeviceError(config_.adapter + ": bus recovery needs both scl and sda lines, or neither");
  }
  if (!config_.rebind) return;
  std::error_code ec;
  const fs::path node = fs::canonical(config_.adapter, ec);
  const std::string name =
      ec ? fs::path(config_.adapter).filename().string() : node.filename().string();  // "i2c-1"
  const fs::path adapter_dir =
      fs::canonical(fs::path(config_.sysfs_root) / "bus" / "i2c" / "devices" / name, ec);
  if (ec) {
    throw DeviceError(config_.adapter + ": bus recovery cannot rebind: no " +
                      (fs::path(config_.sysfs_root) / "bus/i2c/devices" / name).string());
  }
  const fs::path controller_dir = adapter_dir.parent_path();
  const fs::path driver = fs::canonical(controller_dir / "driver", ec);
  if (ec) {
    throw DeviceError(config_.adapter + ": bus recovery cannot rebind: " + controller_dir.string() +
                      " has no driver");
  }
  controller_ = controller_dir.filename().string();
  driver_dir_ = driver.string();
}

bool I2cRecovery::clear_through_gpio() {
  try {
    GpioI2cLines lines(*config_.scl, *config_.sda);
    if (i2c_bus_clear(lines)) {
      ++counters_.cleared;
      return true;
    }
  } catch (const DeviceError&) {
    // The lines could not be requested (still owned by the controller): counted below.
  }
  ++counters_.clear_failures;
  return false;
}

bool I2cRecovery::run(const std::function<void()>& reopen) {
  ++counters_.runs;
  const bool rebind = !controller_.empty();
  bool ok = true;
  bool unbound = false;
  if (rebind) {
    unbound = write_sysfs(driver_dir_ + "/unbind", controller_);
    ok = unbound;
  }
  // The pins are the controller's while its driver is bound: clock them only once it is not
  // (taking them from a bound controller would leave them in their GPIO function).
  if (config_.scl && (!rebind || unbound)) ok = clear_through_gpio() && ok;
  if (rebind) {
    const bool bound = unbound && write_sysfs(driver_dir_ + "/bind", controller_);
    if (bound) {
      ++counters_.rebinds;
    } else {
      ++counters_.rebind_failures;
    }
    ok = ok && bound;
  }
  if (reopen) reopen();
  return ok;
}

}  // namespace wallar::drivers
