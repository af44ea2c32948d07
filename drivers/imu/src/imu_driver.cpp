// SPDX-License-Identifier: Apache-2.0
/// @file imu_driver.cpp
/// @brief Printing the counters every IMU driver keeps.
#include "wallar/drivers/imu/imu_driver.hpp"

namespace wallar::drivers {

std::string format_counters(const ImuCounters& c) {
  std::string out;
  const auto add = [&out](std::string_view name, std::uint64_t v) {
    if (!out.empty()) out += ' ';
    out += name;
    out += '=';
    out += std::to_string(v);
  };
  add("samples", c.samples);
  add("bad_transfer", c.bad_transfer);
  add("nack", c.nack);
  add("short_transfer", c.short_transfer);
  add("fifo_overflow", c.fifo_overflow);
  add("dropped_samples", c.dropped_samples);
  add("missed_data_ready", c.missed_data_ready);
  add("resync", c.resync);
  add("config_mismatch", c.config_mismatch);
  add("resets", c.resets);
  add("probe_failures", c.probe_failures);
  return out;
}

}  // namespace wallar::drivers
