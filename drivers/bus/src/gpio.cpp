// SPDX-License-Identifier: Apache-2.0
/// @file gpio.cpp
/// @brief libgpiod v1 line events: data-ready edges with kernel timestamps, debounced buttons.
#include "wallar/drivers/bus/gpio.hpp"

#include <gpiod.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "wallar/core/error.hpp"

namespace wallar::drivers {
namespace {

[[noreturn]] void fail(const GpioLineSpec& spec, const char* what, int err) {
  throw DeviceError(spec.chip + " line " + std::to_string(spec.line) + ": " + what + ": " +
                    std::strerror(err));
}

timespec to_timespec(DurationNs ns) {
  if (ns < 0) ns = 0;
  return ns_to_timespec(ns);
}

}  // namespace

GpioLineRequest::GpioLineRequest(const GpioLineSpec& spec, const char* consumer, int request_type,
                                 int flags, int initial_value) {
  errno = 0;
  chip_ = gpiod_chip_open_lookup(spec.chip.c_str());
  if (chip_ == nullptr) fail(spec, "cannot open GPIO chip", errno != 0 ? errno : ENODEV);
  line_ = gpiod_chip_get_line(chip_, spec.line);
  if (line_ == nullptr) {
    const int err = errno != 0 ? errno : EINVAL;
    gpiod_chip_close(chip_);
    fail(spec, "no such line", err);
  }
  gpiod_line_request_config config{consumer, request_type, flags};
  if (gpiod_line_request(line_, &config, initial_value) < 0) {
    const int err = errno;
    gpiod_chip_close(chip_);
    fail(spec, "cannot request line", err);
  }
}

GpioLineRequest::~GpioLineRequest() {
  gpiod_line_release(line_);
  gpiod_chip_close(chip_);
}

// Ask for the physical asserting edge and do not invert: the event type then needs no
// interpretation, whatever the kernel's v1 active-low semantics.
GpioEdgeInput::GpioEdgeInput(const GpioLineSpec& spec, const char* consumer)
    : request_(spec, consumer,
               spec.active_low ? GPIOD_LINE_REQUEST_EVENT_FALLING_EDGE
                               : GPIOD_LINE_REQUEST_EVENT_RISING_EDGE,
               0) {}

int GpioEdgeInput::fd() const { return gpiod_line_event_get_fd(request_.line()); }

// Physical levels, no ACTIVE_LOW flag: the start value is then unambiguous (de-asserted).
GpioOutput::GpioOutput(const GpioLineSpec& spec, const char* consumer)
    : request_(spec, consumer, GPIOD_LINE_REQUEST_DIRECTION_OUTPUT, 0, spec.active_low ? 1 : 0),
      active_low_(spec.active_low) {}

void GpioOutput::set(bool asserted) {
  if (gpiod_line_set_value(request_.line(), asserted != active_low_ ? 1 : 0) < 0) ++errors_;
}

std::optional<TimeNs> GpioEdgeInput::wait_edge(DurationNs timeout_ns) {
  const timespec ts = to_timespec(timeout_ns);
  int r = 0;
  do {
    r = gpiod_line_event_wait(request_.line(), &ts);
  } while (r < 0 && errno == EINTR);
  if (r <= 0) {
    if (r < 0) ++errors_;
    return std::nullopt;
  }
  gpiod_line_event event{};
  if (gpiod_line_event_read(request_.line(), &event) < 0) {
    ++errors_;
    return std::nullopt;
  }
  return timespec_to_ns(event.ts);
}

std::optional<bool> Debouncer::on_edge(bool raw_level, TimeNs t_ns) {
  raw_ = raw_level;
  t_last_edge_ns_ = t_ns;
  if (raw_ != reported_ && t_ns - t_reported_ns_ >= window_ns_) {
    reported_ = raw_;
    t_reported_ns_ = t_ns;
    return reported_;
  }
  return std::nullopt;
}

std::optional<bool> Debouncer::settle(TimeNs now_ns) {
  if (raw_ != reported_ && now_ns - t_last_edge_ns_ >= window_ns_ &&
      now_ns - t_reported_ns_ >= window_ns_) {
    reported_ = raw_;
    t_reported_ns_ = now_ns;
    return reported_;
  }
  return std::nullopt;
}

std::optional<TimeNs> Debouncer::settle_deadline() const {
  if (raw_ == reported_) return std::nullopt;
  return std::max(t_last_edge_ns_, t_reported_ns_) + window_ns_;
}

GpioButton::GpioButton(const GpioLineSpec& spec, const char* consumer, DurationNs debounce_ns)
    : request_(spec, consumer, GPIOD_LINE_REQUEST_EVENT_BOTH_EDGES,
               spec.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0),
      // The logical level (active_low applied) at start.
      debouncer_(debounce_ns, gpiod_line_get_value(request_.line()) > 0) {}

int GpioButton::fd() const { return gpiod_line_event_get_fd(request_.line()); }

std::optional<bool> GpioButton::service(DurationNs timeout_ns, TimeNs now_ns) {
  std::optional<bool> changed;
  timespec ts = to_timespec(timeout_ns);
  for (;;) {
    const int r = gpiod_line_event_wait(request_.line(), &ts);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;
    gpiod_line_event event{};
    if (gpiod_line_event_read(request_.line(), &event) < 0) break;
    // With ACTIVE_LOW requested, v1 reports logical edges: RISING means "became asserted".
    const bool level = event.event_type == GPIOD_LINE_EVENT_RISING_EDGE;
    if (auto c = debouncer_.on_edge(level, timespec_to_ns(event.ts))) changed = c;
    ts = timespec{0, 0};  // drain what is pending without waiting again
  }
  if (auto c = debouncer_.settle(now_ns)) changed = c;
  return changed;
}

}  // namespace wallar::drivers
