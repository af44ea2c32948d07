// SPDX-License-Identifier: Apache-2.0
/// @file inputs.cpp
/// @brief Keys and buttons, polled without waiting.
#include "wallar/firmware/appliance/inputs.hpp"

namespace wallar::firmware {
namespace {

drivers::GpioLineSpec gpio_spec(const GpioLine& line) {
  drivers::GpioLineSpec spec;
  spec.chip = line.chip;
  spec.line = static_cast<unsigned>(line.line);
  spec.active_low = line.active_low;
  return spec;
}

}  // namespace

Inputs::Inputs(const BoardConfig& board, const std::string& keys) {
  const std::string& spec = keys.empty() ? board.keys : keys;
  if (!spec.empty()) keys_ = std::make_unique<drivers::EvdevKeys>(spec);
  constexpr DurationNs kDebounceNs = 20 * kNsPerMs;
  if (board.reset_button) {
    reset_ = std::make_unique<drivers::GpioButton>(gpio_spec(*board.reset_button), "wallar-reset",
                                                   kDebounceNs);
  }
  if (board.exit_button) {
    exit_ = std::make_unique<drivers::GpioButton>(gpio_spec(*board.exit_button), "wallar-exit",
                                                  kDebounceNs);
  }
}

drivers::InputAction Inputs::poll(TimeNs now_ns) {
  if (keys_ && !keys_->lost()) {
    const drivers::InputAction a = keys_->poll(0);
    if (a != drivers::InputAction::kNone) return a;
  }
  if (exit_) {
    if (const auto pressed = exit_->service(0, now_ns); pressed && *pressed)
      return drivers::InputAction::kExit;
  }
  if (reset_) {
    if (const auto pressed = reset_->service(0, now_ns); pressed && *pressed)
      return drivers::InputAction::kReset;
  }
  return drivers::InputAction::kNone;
}

std::string Inputs::describe() const {
  std::string s;
  if (keys_) s += "keys";
  if (reset_) s += s.empty() ? "reset button" : ", reset button";
  if (exit_) s += s.empty() ? "exit button" : ", exit button";
  return s.empty() ? "none" : s;
}

}  // namespace wallar::firmware
