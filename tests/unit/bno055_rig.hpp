// SPDX-License-Identifier: Apache-2.0
/// @file bno055_rig.hpp
/// @brief The BNO055 UART driver wired to the pty simulator, pumped deterministically from
/// the test loop on a fake clock: step the driver, let the sim answer, wait until the answer
/// is readable, step again.
///
/// Threading: test thread only.
#pragma once

#include <poll.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <vector>

#include "bno055_sim.hpp"
#include "wallar/drivers/imu/bno055_uart.hpp"

namespace wallar::test {

class CollectSink : public drivers::ImuSampleSink {
 public:
  void on_imu_sample(const ImuSample& s) noexcept override { samples.push_back(s); }
  std::vector<ImuSample> samples;
};

/// Which motion(n) a sample carries (acc.x holds n, 100 LSB per m/s^2).
inline std::uint32_t burst_index(const ImuSample& s) {
  return static_cast<std::uint32_t>(std::lround(s.accel_m_s2.x() * 100.0));
}

class Bno055Rig {
 public:
  explicit Bno055Rig(drivers::Bno055UartConfig cfg = {}) {
    cfg.device = sim.slave_path();
    driver = std::make_unique<drivers::Bno055Uart>(cfg, sink);
  }

  /// One round: driver step at `now`, sim answers, time advances to when the driver wants to
  /// run (or just past now when an answer is on its way).
  void tick() { answer_and_advance(step_driver()); }
  /// The two halves of tick(), apart so a test can watch the driver's step alone.
  TimeNs step_driver() { return driver->step(now, std::nullopt); }
  void answer_and_advance(TimeNs wake) {
    const std::size_t written = sim.pump(now, driver->uart_counters().requests);
    if (written > 0 && driver->fd() >= 0) {
      pollfd p{driver->fd(), POLLIN, 0};
      ::poll(&p, 1, 2000);
      now += 100 * kNsPerUs;  // the answer came while the thread slept
    } else {
      now = std::max(wake, now + 1);
    }
  }
  template <class Done>
  bool run_until(Done done, DurationNs max_ns) {
    const TimeNs end = now + max_ns;
    while (now < end) {
      tick();
      if (done()) return true;
    }
    return false;
  }
  void run_for(DurationNs d) {
    run_until([] { return false; }, d);
  }
  /// Lets the driver take in an answer already on its way, without the sim answering
  /// anything new: afterwards every burst the sim served has been seen by the driver.
  void drain() {
    for (int i = 0; i < 5 && driver->awaiting_response() && driver->fd() >= 0; ++i) {
      pollfd p{driver->fd(), POLLIN, 0};
      ::poll(&p, 1, 50);
      now += 100 * kNsPerUs;
      driver->step(now, std::nullopt);
    }
  }
  bool reach_run(DurationNs max_ns = 3 * kNsPerS) {
    return run_until([this] { return driver->state() == drivers::ImuDriverState::kRun; }, max_ns);
  }
  [[nodiscard]] const drivers::ImuCounters& counters() const { return driver->counters(); }

  Bno055Sim sim;
  CollectSink sink;
  std::unique_ptr<drivers::Bno055Uart> driver;
  TimeNs now = 1000 * kNsPerS;
};

}  // namespace wallar::test
