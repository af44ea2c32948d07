// SPDX-License-Identifier: Apache-2.0
/// @file live_imu.cpp
/// @brief Opening the board's IMU and the imu thread's wait-and-step loop.
#include "wallar/firmware/live_imu.hpp"

#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <stdexcept>

#include "wallar/core/error.hpp"
#include "wallar/drivers/bus/gpio.hpp"
#include "wallar/drivers/bus/i2c.hpp"
#include "wallar/drivers/bus/i2c_recovery.hpp"
#include "wallar/drivers/imu/bno055_uart.hpp"
#include "wallar/drivers/imu/icm20948.hpp"
#include "wallar/drivers/usb/usb.hpp"

namespace wallar::firmware {

struct LiveImu::Parts {
  std::unique_ptr<drivers::LinuxI2cAdapter> adapter;
  std::unique_ptr<drivers::I2cRecovery> recovery;
  std::unique_ptr<drivers::I2cBus> bus;
  std::unique_ptr<drivers::GpioEdgeInput> data_ready;
  std::unique_ptr<drivers::ImuDriver> driver;
  drivers::Bno055Uart* bno055 = nullptr;  // the serial driver, for its fd
};

std::string find_usb_tty(const std::string& usb_id) {
  const drivers::UsbId id = drivers::parse_usb_id(usb_id, "imu.usb_id");
  drivers::UsbContext usb;
  for (const drivers::UsbDeviceInfo& dev : usb.enumerate(id)) {
    if (!dev.nodes.tty.empty()) return dev.nodes.tty.front();
    throw DeviceError("USB device " + usb_id + " at " + dev.port_path() +
                      " has no tty (is its usb-serial driver loaded?)");
  }
  throw DeviceError("USB device " + usb_id + " not found (plugged in?)");
}

LiveImu::LiveImu(const BoardConfig& board, drivers::ImuSampleSink& sink, LogRing* ring)
    : parts_(std::make_unique<Parts>()), ring_(ring) {
  const ImuConfig& imu = board.imu;
  if (imu.driver == "icm20948") {
    parts_->adapter = std::make_unique<drivers::LinuxI2cAdapter>(imu.bus);
    // A stuck bus (every transfer failing) is freed as the board says; the bus counts the
    // attempt, the driver's full reset follows.
    drivers::I2cRecoveryHook hook;
    if (imu.bus_recovery) {
      drivers::I2cRecoveryConfig rc;
      rc.adapter = imu.bus;
      rc.rebind = imu.bus_recovery->rebind;
      const auto line = [](const GpioLine& g) {
        return drivers::GpioLineSpec{g.chip, static_cast<unsigned>(g.line), g.active_low};
      };
      if (imu.bus_recovery->scl) rc.scl = line(*imu.bus_recovery->scl);
      if (imu.bus_recovery->sda) rc.sda = line(*imu.bus_recovery->sda);
      parts_->recovery = std::make_unique<drivers::I2cRecovery>(rc);
      hook = [parts = parts_.get()] {
        parts->recovery->run([parts] { parts->adapter->reopen(); });
      };
    }
    parts_->bus = std::make_unique<drivers::I2cBus>(*parts_->adapter, imu.address,
                                                    drivers::I2cBus::Options{}, std::move(hook));
    drivers::Icm20948::Config config;
    config.rate_hz = imu.rate_hz;
    config.fifo_read_every = static_cast<unsigned>(imu.fifo_batch);
    config.has_data_ready = imu.data_ready.has_value();
    if (imu.data_ready) {
      parts_->data_ready = std::make_unique<drivers::GpioEdgeInput>(
          drivers::GpioLineSpec{imu.data_ready->chip, static_cast<unsigned>(imu.data_ready->line),
                                imu.data_ready->active_low},
          "wallar-imu-drdy");
    }
    auto driver = std::make_unique<drivers::Icm20948>(*parts_->bus, config, sink);
    nominal_rate_hz_ = driver->rate_hz();
    parts_->driver = std::move(driver);
    char addr[8];
    std::snprintf(addr, sizeof addr, "0x%02x", imu.address);
    description_ = "icm20948 on " + imu.bus + " @" + addr;
    device_ = imu.bus;
    if (imu.data_ready)
      description_ +=
          ", data-ready " + imu.data_ready->chip + ":" + std::to_string(imu.data_ready->line);
    if (imu.fifo_batch > 1) description_ += ", " + std::to_string(imu.fifo_batch) + " per read";
    if (parts_->recovery) {
      description_ += ", bus recovery:";
      if (!parts_->recovery->controller().empty())
        description_ += " rebind " + parts_->recovery->controller();
      if (imu.bus_recovery->scl) description_ += " clear";
    }
  } else if (imu.driver == "bno055") {
    drivers::Bno055UartConfig config;
    config.device = imu.bus.empty() ? find_usb_tty(imu.usb_id) : imu.bus;
    config.baud = imu.baud;
    config.rate_hz = std::min(imu.rate_hz, 100.0);
    auto driver = std::make_unique<drivers::Bno055Uart>(config, sink);
    parts_->bno055 = driver.get();
    nominal_rate_hz_ = config.rate_hz;
    parts_->driver = std::move(driver);
    description_ = "bno055 on " + config.device + " at " + std::to_string(config.baud) + " baud";
    device_ = config.device;
  } else {
    throw_input_error(board.file.string(), 0, "the board names no IMU (imu.driver: none)");
  }
}

LiveImu::~LiveImu() = default;

const drivers::ImuDriver& LiveImu::driver() const { return *parts_->driver; }

void LiveImu::run(TimeNs until_ns, const std::atomic<bool>& stop) {
  drivers::ImuDriver& driver = *parts_->driver;
  std::optional<TimeNs> edge_ns;
  StartupRate rate(kRateWindowNs);
  while (!stop.load(std::memory_order_relaxed)) {
    TimeNs now_ns = monotonic_now_ns();
    heartbeat_.beat(now_ns);
    if (now_ns >= until_ns) return;
    if (!rate.done()) {
      if (const std::optional<double> hz = rate.update(now_ns, driver.counters().samples)) {
        report_rate(*hz);
      }
    }
    const TimeNs wake_ns = std::min(driver.step(now_ns, edge_ns), until_ns);
    edge_ns.reset();
    // What to wait on: the data-ready line, or the serial port's bytes.
    int fd = -1;
    if (parts_->data_ready) fd = parts_->data_ready->fd();
    if (parts_->bno055) fd = parts_->bno055->fd();
    now_ns = monotonic_now_ns();
    // Cap each wait so a stop request is seen within 100 ms.
    const DurationNs wait_ns = std::clamp<DurationNs>(wake_ns - now_ns, 0, 100 * kNsPerMs);
    if (fd < 0) {
      const timespec ts = ns_to_timespec(wait_ns);
      ::nanosleep(&ts, nullptr);
      continue;
    }
    pollfd pfd{fd, POLLIN, 0};
    const int timeout_ms = static_cast<int>((wait_ns + kNsPerMs - 1) / kNsPerMs);
    const int n = ::poll(&pfd, 1, timeout_ms);
    if (n > 0 && (pfd.revents & POLLIN) != 0 && parts_->data_ready) {
      edge_ns = parts_->data_ready->wait_edge(0);  // pending: returns at once with its stamp
    }
    // n < 0 (EINTR) or a timeout: step again, the driver decides what is due.
  }
}

std::optional<double> StartupRate::update(TimeNs now_ns, std::uint64_t samples) {
  if (done_) return std::nullopt;
  if (t_start_ns_ < 0) t_start_ns_ = now_ns;
  if (t_first_ns_ < 0 && samples > 0) {
    t_first_ns_ = now_ns;
    samples_at_first_ = samples;
  }
  if (t_first_ns_ >= 0 && now_ns - t_first_ns_ >= window_ns_) {
    done_ = true;
    return static_cast<double>(samples - samples_at_first_) / ns_to_s(now_ns - t_first_ns_);
  }
  if (t_first_ns_ < 0 && now_ns - t_start_ns_ >= window_ns_) {
    done_ = true;
    return 0.0;
  }
  return std::nullopt;
}

void LiveImu::report_rate(double measured_hz) {
  measured_rate_hz_ = measured_hz;
  // A record for the log thread on the appliance (numbers only on this SCHED_FIFO thread); a
  // line on stderr for record and imu.
  say_imu_rate(ns_to_s(kRateWindowNs), measured_hz, nominal_rate_hz_, device_.c_str(),
               drivers::to_string(parts_->driver->state()).data(),  // a literal
               ring_,
               [](const std::string& l) { std::fprintf(stderr, "wallar: %s\n", l.c_str()); });
}

void say_imu_rate(double window_s, double measured_hz, double nominal_hz, const char* device,
                  const char* driver_state, LogRing* ring,
                  const std::function<void(const std::string&)>& fallback) {
  static constexpr const char* kLine = "imu rate over %g s: %.1f Hz (nominal %g Hz)";
  static constexpr const char* kOff =
      "WARNING: imu (%s): it delivers %.1f Hz, not the %g Hz it runs at for imu.rate_hz: "
      "samples are being lost (check the data-ready line, the bus speed and the imu thread's "
      "CPU)";
  static constexpr const char* kNone =
      "WARNING: imu (%s): no sample in its first %g s (driver state %s): check its wiring and "
      "the board's imu section (imu.driver, imu.bus, imu.address)";
  const bool none = measured_hz <= 0.0;
  const bool off = !none && !rate_ok(measured_hz, nominal_hz);
  const auto say = [&](const char* format, std::initializer_list<LogArg> args) {
    post_or_log(ring, fallback, format, args, device);
  };
  if (none) {
    say(kNone, {LogArg::copied(), window_s, driver_state});
    return;
  }
  say(kLine, {window_s, measured_hz, nominal_hz});
  if (off) say(kOff, {LogArg::copied(), measured_hz, nominal_hz});
}

}  // namespace wallar::firmware
