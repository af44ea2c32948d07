// SPDX-License-Identifier: Apache-2.0
/// @file systemd_notify.hpp
/// @brief The service manager's side of the appliance: readiness, status line, stopping and
/// the watchdog keep-alive, through libsystemd's sd_notify() (Type=notify units).
///
/// Under systemd (NOTIFY_SOCKET set) each call sends one datagram to the manager; otherwise
/// (a shell, a test, another init) every call is a no-op and active() is false. Nothing
/// throws; a failed send is counted in errors(). No call allocates: texts are formatted into
/// a fixed buffer.
///
/// Watchdog: with WatchdogSec= in the unit, systemd sets WATCHDOG_USEC (and WATCHDOG_PID) and
/// restarts the service (Restart=on-failure) when no "WATCHDOG=1" arrives for that long after
/// READY=1. The supervisor calls watchdog(now) from its loop only while every module it
/// watches is alive, so a hung module stops the keep-alive; it may also ask for the restart at
/// once with watchdog_trigger().
///
/// Threading: one thread (the supervisor) owns the notifier; it is not shared. The
/// environment is read once, by the constructor.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "wallar/core/time.hpp"

namespace wallar::firmware {

class SystemdNotifier {
 public:
  /// Reads NOTIFY_SOCKET and the watchdog period (sd_watchdog_enabled: WATCHDOG_USEC, for
  /// this process when WATCHDOG_PID names it). The environment is left as it is.
  SystemdNotifier();

  /// Running under a service manager that listens (NOTIFY_SOCKET set).
  [[nodiscard]] bool active() const { return active_; }
  /// The watchdog timeout systemd enforces; 0 = no watchdog (or not under systemd).
  [[nodiscard]] DurationNs watchdog_period_ns() const { return watchdog_period_ns_; }

  /// "READY=1": start-up finished (devices open, threads running); systemd starts the
  /// watchdog and the units ordered after this one.
  void ready();
  /// "STATUS=<line>" (shown by systemctl status). Control characters (a newline would start
  /// another assignment) become spaces; longer than kMaxStatusChars is cut. nullptr = "".
  void status(const char* line);
  /// "STOPPING=1": shutting down (after SIGTERM or an exit key).
  void stopping();

  /// A keep-alive is due: the watchdog is on and none was sent for half its period.
  [[nodiscard]] bool watchdog_due(TimeNs now_ns) const;
  /// "WATCHDOG=1" when watchdog_due(now_ns) (at most every half period), else nothing.
  void watchdog(TimeNs now_ns);
  /// "WATCHDOG=trigger": systemd acts as if the watchdog timed out (restart per the unit's
  /// Restart=). For a module that hangs: restarting now beats waiting for the timeout.
  void watchdog_trigger();

  /// Datagrams sent, and sends that failed (sd_notify < 0; the last errno in last_errno()).
  [[nodiscard]] std::uint64_t sent() const { return sent_; }
  [[nodiscard]] std::uint64_t errors() const { return errors_; }
  [[nodiscard]] int last_errno() const { return last_errno_; }

  static constexpr std::size_t kMaxStatusChars = 200;

 private:
  void send(const char* state);

  bool active_ = false;
  DurationNs watchdog_period_ns_ = 0;
  bool watchdog_sent_ = false;
  TimeNs last_watchdog_ns_ = 0;
  std::uint64_t sent_ = 0;
  std::uint64_t errors_ = 0;
  int last_errno_ = 0;
  std::array<char, sizeof("STATUS=") + kMaxStatusChars> buffer_{};
};

}  // namespace wallar::firmware
