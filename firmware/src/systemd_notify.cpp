// SPDX-License-Identifier: Apache-2.0
/// @file systemd_notify.cpp
/// @brief sd_notify() messages (READY, STATUS, STOPPING, WATCHDOG) for SystemdNotifier.
#include "wallar/firmware/systemd_notify.hpp"

#include <systemd/sd-daemon.h>

#include <cstdint>
#include <cstdlib>

namespace wallar::firmware {

SystemdNotifier::SystemdNotifier() {
  const char* socket = std::getenv("NOTIFY_SOCKET");
  active_ = socket != nullptr && socket[0] != '\0';
  std::uint64_t usec = 0;
  // > 0: the watchdog is on for this process (WATCHDOG_PID unset or ours); keep the
  // environment (0) so a later notifier reads the same.
  if (active_ && sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    watchdog_period_ns_ = static_cast<DurationNs>(usec) * kNsPerUs;
  }
}

void SystemdNotifier::send(const char* state) {
  if (!active_) return;
  const int r = sd_notify(0, state);
  if (r < 0) {
    ++errors_;
    last_errno_ = -r;
  } else if (r > 0) {
    ++sent_;
  }
}

void SystemdNotifier::ready() { send("READY=1"); }

void SystemdNotifier::stopping() { send("STOPPING=1"); }

void SystemdNotifier::status(const char* line) {
  if (!active_) return;
  constexpr char kKey[] = "STATUS=";
  std::size_t n = 0;
  for (const char* k = kKey; *k != '\0'; ++k) buffer_[n++] = *k;
  const std::size_t end = n + kMaxStatusChars;
  for (const char* c = line; c != nullptr && *c != '\0' && n < end; ++c) {
    const auto u = static_cast<unsigned char>(*c);
    buffer_[n++] = (u < 0x20 || u == 0x7f) ? ' ' : *c;
  }
  buffer_[n] = '\0';
  send(buffer_.data());
}

bool SystemdNotifier::watchdog_due(TimeNs now_ns) const {
  if (!active_ || watchdog_period_ns_ <= 0) return false;
  return !watchdog_sent_ || now_ns - last_watchdog_ns_ >= watchdog_period_ns_ / 2;
}

void SystemdNotifier::watchdog(TimeNs now_ns) {
  if (!watchdog_due(now_ns)) return;
  send("WATCHDOG=1");
  // Also after a failed send: retrying at every call would not help a broken socket.
  watchdog_sent_ = true;
  last_watchdog_ns_ = now_ns;
}

void SystemdNotifier::watchdog_trigger() { send("WATCHDOG=trigger"); }

}  // namespace wallar::firmware
