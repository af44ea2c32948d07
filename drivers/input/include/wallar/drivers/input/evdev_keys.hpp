// SPDX-License-Identifier: Apache-2.0
/// @file evdev_keys.hpp
/// @brief A keyboard (or headset remote) read through Linux evdev: key presses mapped to the
/// appliance's actions (reset the map, exit), with only <linux/input.h> ioctls (no libevdev).
///
/// The device is named by its path (/dev/input/eventN, or a stable /dev/input/by-id/... or
/// by-path link) or as "name:SUBSTRING", which picks the first /dev/input/eventN (in numeric
/// order) whose EVIOCGNAME contains SUBSTRING (case-insensitive) and which has at least one
/// bound key. Opening may throw (start-up); poll() never throws and never allocates: a device
/// that goes away (unplugged, ENODEV, POLLHUP/POLLERR) sets lost(), and the owner may build a
/// new EvdevKeys from spec() to reopen it.
///
/// Only key presses (EV_KEY, value 1) count: releases (0) and auto-repeats (2) never trigger
/// an action, so holding a key resets once.
///
/// Threading: one owner thread. fd() may be handed to that thread's poll()/epoll; nothing is
/// shared. Move-only; the destructor closes the descriptor (which also releases a grab).
#pragma once

#include <linux/input.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/core/time.hpp"

namespace wallar::drivers {

/// What a key press asks the appliance to do.
enum class InputAction : std::uint8_t { kNone, kReset, kExit };

/// An evdev key code (KEY_*, 0..KEY_MAX) and the action its press triggers.
struct KeyBinding {
  int code;
  InputAction action;
};

/// The default bindings: R resets, Q and Esc exit.
inline constexpr std::array<KeyBinding, 3> kDefaultKeyBindings{{
    {KEY_R, InputAction::kReset},
    {KEY_Q, InputAction::kExit},
    {KEY_ESC, InputAction::kExit},
}};

/// "none", "reset" or "exit" (for logs).
[[nodiscard]] const char* to_string(InputAction action);

/// What poll() has seen since construction.
struct EvdevKeyCounters {
  std::uint64_t events = 0;           //!< input_events decoded (every type, SYN included)
  std::uint64_t presses = 0;          //!< EV_KEY value 1 (bound or not)
  std::uint64_t unbound_presses = 0;  //!< presses of keys with no binding
  std::uint64_t dropped = 0;          //!< SYN_DROPPED: the kernel's buffer overflowed
};

class EvdevKeys {
 public:
  /// Opens the device `spec` names (a path, or "name:SUBSTRING"; see the file comment)
  /// O_RDONLY | O_NONBLOCK | O_CLOEXEC and checks (EVIOCGBIT(EV_KEY)) that it has at least one
  /// bound key. With `grab`, takes the device exclusively (EVIOCGRAB: the console and other
  /// readers stop seeing its keys). Throws wallar::DeviceError on one line:
  /// "<path>: cannot open input device: <strerror>", "<path>: not an evdev device
  /// (EVIOCGBIT): <strerror>", "<path>: no reset/exit keys (not a keyboard?)",
  /// "<path>: cannot grab (EVIOCGRAB): <strerror>", or for a search
  /// "name:SUBSTRING: no input device ... among /dev/input/event* ...". Throws
  /// std::invalid_argument for a binding code outside 0..KEY_MAX.
  explicit EvdevKeys(std::string_view spec, bool grab = false,
                     std::span<const KeyBinding> bindings = kDefaultKeyBindings);

  /// Adopts an already-open descriptor (ownership passes even when this throws; it is made
  /// non-blocking and close-on-exec). `name` stands for the path in messages. With
  /// `check_device` the evdev checks (and `grab`) of the other constructor apply; without,
  /// no ioctl is made, so any byte stream of struct input_event works (tests use a pipe).
  /// Throws wallar::DeviceError as above (or "<name>: bad file descriptor" for fd < 0).
  EvdevKeys(int fd, std::string name, bool check_device, bool grab = false,
            std::span<const KeyBinding> bindings = kDefaultKeyBindings);

  ~EvdevKeys();
  EvdevKeys(const EvdevKeys&) = delete;
  EvdevKeys& operator=(const EvdevKeys&) = delete;
  EvdevKeys(EvdevKeys&& other) noexcept;
  EvdevKeys& operator=(EvdevKeys&& other) noexcept;

  /// The descriptor, for poll()/epoll (POLLIN when events are pending). -1 after a move.
  [[nodiscard]] int fd() const { return fd_; }

  /// Returns the action of the first bound key press among the pending events, waiting up to
  /// timeout_ns (<= 0: do not wait) for events to arrive. Reads what the descriptor has ready
  /// (decoding events split across reads); events after a bound press stay buffered for the
  /// next call, so two quick presses are both seen. Returns kNone on timeout, when the events
  /// read had no bound press (it may then return before the timeout), and at once when lost().
  /// Never throws, never allocates.
  InputAction poll(DurationNs timeout_ns);

  /// The device is gone (unplugged, read error, end of stream): poll() returns kNone at once.
  [[nodiscard]] bool lost() const { return lost_; }
  /// Why lost() is true, on one line naming the device ("" while not lost).
  [[nodiscard]] const char* last_error() const { return last_error_.data(); }

  [[nodiscard]] const EvdevKeyCounters& counters() const { return counters_; }
  /// The spec given to the constructor (or the adopted fd's name): build a new EvdevKeys from
  /// it to reopen a lost device.
  [[nodiscard]] const std::string& spec() const { return spec_; }
  /// The device node opened ("name:..." resolved), or the adopted fd's name.
  [[nodiscard]] const std::string& path() const { return path_; }
  /// The device's name (EVIOCGNAME), "" when not checked.
  [[nodiscard]] const std::string& device_name() const { return device_name_; }
  [[nodiscard]] bool grabbed() const { return grabbed_; }

 private:
  static constexpr std::size_t kBufferEvents = 64;

  void set_bindings(std::span<const KeyBinding> bindings);
  void check_and_grab(bool grab);
  void close_fd() noexcept;
  // Decodes the complete events buffered; returns the first bound press (consuming the
  // events up to it) or kNone (consuming all complete events, keeping a partial one).
  InputAction decode();
  // Reads what is ready into the buffer, decoding as it goes; sets lost_ on EOF or error.
  InputAction drain();
  void mark_lost(const char* what, int err) noexcept;

  int fd_ = -1;
  std::string spec_;
  std::string path_;
  std::string device_name_;
  std::vector<KeyBinding> bindings_;
  bool grabbed_ = false;
  bool lost_ = false;
  EvdevKeyCounters counters_;
  std::size_t buffered_ = 0;  // bytes in buffer_ (from its start)
  std::array<unsigned char, kBufferEvents * sizeof(input_event)> buffer_{};
  std::array<char, 256> last_error_{};
};

}  // namespace wallar::drivers
