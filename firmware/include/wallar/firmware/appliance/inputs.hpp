// SPDX-License-Identifier: Apache-2.0
/// @file inputs.hpp
/// @brief The appliance's inputs: an evdev keyboard (R resets tracking and map, Q/Esc exit)
/// and the board's GPIO reset and exit buttons (libgpiod, debounced). Opened at construction
/// (a missing device is an error at start), polled by the supervisor without waiting.
///
/// Threading: one thread (the supervisor) builds and polls it.
#pragma once

#include <memory>
#include <string>

#include "wallar/drivers/bus/gpio.hpp"
#include "wallar/drivers/input/evdev_keys.hpp"
#include "wallar/firmware/board.hpp"

namespace wallar::firmware {

class Inputs {
 public:
  /// `keys`: "/dev/input/eventN", "name:TEXT", or empty for no keyboard.
  Inputs(const BoardConfig& board, const std::string& keys);
  /// The action pending now, if any; never waits.
  drivers::InputAction poll(TimeNs now_ns);
  [[nodiscard]] std::string describe() const;

 private:
  std::unique_ptr<drivers::EvdevKeys> keys_;
  std::unique_ptr<drivers::GpioButton> reset_, exit_;
};

}  // namespace wallar::firmware
