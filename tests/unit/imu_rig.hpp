// SPDX-License-Identifier: Apache-2.0
/// @file imu_rig.hpp
/// @brief The ICM-20948 driver on its I2cBus on the simulator, run in simulated time the way the
/// imu thread runs it: wake at the data-ready edge (with its timestamp) or at the deadline the
/// driver asked for.
///
/// Threading: test-thread only.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "icm20948_sim.hpp"
#include "wallar/drivers/bus/i2c.hpp"
#include "wallar/drivers/imu/icm20948.hpp"

namespace wallar::test {

/// Keeps every sample (reserve first where allocations are counted).
class CollectingSink final : public drivers::ImuSampleSink {
 public:
  void on_imu_sample(const ImuSample& s) noexcept override {
    if (samples.size() < samples.capacity() || !no_grow) samples.push_back(s);
    ++count;
  }
  std::vector<ImuSample> samples;
  std::uint64_t count = 0;
  bool no_grow = false;
};

struct ImuRig {
  explicit ImuRig(drivers::Icm20948::Config config = {}, SimTruthFn truth = {},
                  drivers::I2cBus::Options bus_options = {})
      : sim(0x68, std::move(truth)),
        bus(sim, 0x68, bus_options, [this] { ++recoveries; }),
        driver(bus, config, sink) {}

  /// Steps until t_end (inclusive of an edge at t_end).
  void run_until(TimeNs t_end) {
    while (now <= t_end) {
      const auto sample_t = sim.next_sample_time();
      TimeNs t_edge = std::numeric_limits<TimeNs>::max();
      if (sample_t && sim.data_ready_enabled()) t_edge = *sample_t;
      TimeNs t = std::max(now, std::min(next_wake, t_edge));
      if (t > t_end) break;
      sim.advance_to(t);
      now = t;
      if (now < stall_until) {  // the imu thread is stalled: its wake-ups and edges are lost
        next_wake = stall_until;
        continue;
      }
      const bool edge = t == t_edge && edges;
      const auto before = driver.state();
      next_wake = driver.step(now, edge ? std::optional<TimeNs>(now) : std::nullopt);
      if (driver.state() == drivers::ImuDriverState::kRun &&
          before != drivers::ImuDriverState::kRun) {
        t_run = now;
        samples_at_run = sink.samples.size();
        counters_at_run = driver.counters();
      }
      ++steps;
    }
    now = std::max(now, t_end);
  }

  /// Samples the chip put into (or lost from) its FIFO since the driver last entered RUN,
  /// minus those still inside.
  [[nodiscard]] std::uint64_t generated_since_run() const {
    return sim.fifo_samples_between(t_run, now) - sim.fifo_bytes() / 12;
  }

  Icm20948Sim sim;
  int recoveries = 0;
  drivers::I2cBus bus;
  CollectingSink sink;
  drivers::Icm20948 driver;
  TimeNs now = 0;
  TimeNs next_wake = 0;
  bool edges = true;
  TimeNs stall_until = -1;
  TimeNs t_run = -1;
  std::size_t samples_at_run = 0;
  drivers::ImuCounters counters_at_run;
  std::uint64_t steps = 0;
};

}  // namespace wallar::test
