// SPDX-License-Identifier: Apache-2.0
/// @file gpio.hpp
/// @brief GPIO through libgpiod v1 (1.6): a data-ready edge line with kernel timestamps, a
/// debounced button, an output (camera trigger), plus the pure pieces (timestamp conversion,
/// debounce) they use.
///
/// The kernel stamps each edge event in its interrupt handler with CLOCK_MONOTONIC (gpiolib
/// cdev, v1 line events carry ktime_get_ns() in gpiod_line_event.ts): that stamp, not the
/// time the thread woke, is when the sensor's sample became ready. (Since Linux 5.7; older
/// kernels stamped v1 events with CLOCK_REALTIME, which would put every sample decades off:
/// the boards we support run 6.x.)
///
/// Threading: each input belongs to one thread (the thread that polls its fd); nothing is
/// shared. wait_edge()/service() never block longer than the timeout they are given.
#pragma once

#include <cstdint>
#include <ctime>
#include <optional>
#include <string>

#include "wallar/core/time.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace wallar::drivers {

/// A kernel event timestamp (CLOCK_MONOTONIC timespec) in ns.
constexpr TimeNs timespec_to_ns(const timespec& ts) {
  return static_cast<TimeNs>(ts.tv_sec) * kNsPerS + static_cast<TimeNs>(ts.tv_nsec);
}

/// Where a line is: chip (name "gpiochip4", path "/dev/gpiochip4" or number "4") and offset.
struct GpioLineSpec {
  std::string chip;
  unsigned line = 0;
  bool active_low = false;  //!< the signal is asserted at the low level
};

/// One requested line and the chip it belongs to (RAII): the handle every GPIO class below
/// holds. Released (line, then chip) on destruction.
class GpioLineRequest {
 public:
  /// Opens the chip and requests the line (libgpiod request type and flags, the initial value
  /// for outputs). Throws wallar::DeviceError "CHIP line N: cannot ...: STRERROR".
  GpioLineRequest(const GpioLineSpec& spec, const char* consumer, int request_type, int flags,
                  int initial_value = 0);
  ~GpioLineRequest();
  GpioLineRequest(const GpioLineRequest&) = delete;
  GpioLineRequest& operator=(const GpioLineRequest&) = delete;
  [[nodiscard]] gpiod_line* line() const { return line_; }

 private:
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
};

/// A data-ready (interrupt) input: requests the asserting edge only (rising, or falling when
/// active_low) and hands out each event's kernel timestamp.
class GpioEdgeInput {
 public:
  /// Throws wallar::DeviceError "CHIP line N: cannot ...: STRERROR" when the chip cannot be
  /// opened or the line cannot be requested (busy, out of range).
  GpioEdgeInput(const GpioLineSpec& spec, const char* consumer);
  GpioEdgeInput(const GpioEdgeInput&) = delete;
  GpioEdgeInput& operator=(const GpioEdgeInput&) = delete;

  /// The event fd, for poll()/epoll (POLLIN when an edge is pending).
  [[nodiscard]] int fd() const;
  /// Waits up to timeout_ns for an edge; returns its kernel timestamp, or nullopt on timeout
  /// (or on an error, which is counted in errors()).
  std::optional<TimeNs> wait_edge(DurationNs timeout_ns);
  [[nodiscard]] std::uint64_t errors() const { return errors_; }

 private:
  GpioLineRequest request_;
  std::uint64_t errors_ = 0;
};

/// An output line (a camera trigger): requested as output, initially de-asserted.
/// set(true) drives the asserted level (low when active_low).
class GpioOutput {
 public:
  /// Throws wallar::DeviceError "CHIP line N: cannot ...: STRERROR" as GpioEdgeInput does.
  GpioOutput(const GpioLineSpec& spec, const char* consumer);
  GpioOutput(const GpioOutput&) = delete;
  GpioOutput& operator=(const GpioOutput&) = delete;
  /// Drives the line; a failure is counted in errors(), never thrown (fixed-rate callers).
  void set(bool asserted);
  [[nodiscard]] std::uint64_t errors() const { return errors_; }

 private:
  GpioLineRequest request_;
  bool active_low_ = false;
  std::uint64_t errors_ = 0;
};

/// Debounce by time for a two-state input seen through its edges (pure: no I/O, no clock).
///
/// The first change after a quiet `window_ns` is reported at once (no added latency); edges
/// within the window after a reported change are bounce and ignored, except that when the
/// line has settled at a level other than the reported one for a full window, that level is
/// reported by settle() (a press and release shorter than the window are not lost).
class Debouncer {
 public:
  Debouncer(DurationNs window_ns, bool initial_level)
      : window_ns_(window_ns), raw_(initial_level), reported_(initial_level) {}

  /// An edge: the line is at raw_level since t_ns. Returns the new debounced level if it
  /// changed.
  std::optional<bool> on_edge(bool raw_level, TimeNs t_ns);
  /// No edge since; time is now_ns. Returns the new debounced level if the line settled at a
  /// level different from the reported one.
  std::optional<bool> settle(TimeNs now_ns);
  /// When settle() should be called next, or nullopt when nothing is pending.
  [[nodiscard]] std::optional<TimeNs> settle_deadline() const;
  [[nodiscard]] bool level() const { return reported_; }

 private:
  DurationNs window_ns_;
  bool raw_;
  bool reported_;
  TimeNs t_last_edge_ns_ = INT64_MIN / 2;
  TimeNs t_reported_ns_ = INT64_MIN / 2;
};

/// A push button on a GPIO line: both edges, debounced in software by the events' kernel
/// timestamps. pressed() is the logical level (active_low honoured).
class GpioButton {
 public:
  /// Throws wallar::DeviceError naming chip and line when it cannot be opened or requested.
  GpioButton(const GpioLineSpec& spec, const char* consumer, DurationNs debounce_ns);
  GpioButton(const GpioButton&) = delete;
  GpioButton& operator=(const GpioButton&) = delete;

  [[nodiscard]] int fd() const;
  /// Reads the pending edges (waiting up to timeout_ns for the first one) and settles the
  /// debouncer at now_ns. Returns the new pressed state when it changed.
  std::optional<bool> service(DurationNs timeout_ns, TimeNs now_ns);
  [[nodiscard]] bool pressed() const { return debouncer_.level(); }

 private:
  GpioLineRequest request_;  // before debouncer_: its initial level is read from the line
  Debouncer debouncer_;
};

}  // namespace wallar::drivers
