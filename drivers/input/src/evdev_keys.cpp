// SPDX-License-Identifier: Apache-2.0
/// @file evdev_keys.cpp
/// @brief evdev key reading: device lookup by name, capability check (EVIOCGBIT), grab,
/// and a non-allocating poll() that decodes struct input_event from a byte buffer.
#include "wallar/drivers/input/evdev_keys.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <climits>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace wallar::drivers {
namespace {

constexpr std::string_view kNamePrefix = "name:";
constexpr const char* kInputDir = "/dev/input";
constexpr int kOpenFlags = O_RDONLY | O_NONBLOCK | O_CLOEXEC;
// poll() reads at most this many buffers per call, so a device that never stops sending
// (a pipe kept full, a chattering HID) cannot hold the caller.
constexpr int kMaxReadsPerPoll = 16;

constexpr std::size_t kBitsPerLong = sizeof(unsigned long) * CHAR_BIT;
using KeyBits = std::array<unsigned long, (KEY_MAX + kBitsPerLong) / kBitsPerLong>;

// strerror without the allocation glibc makes for an unknown errno (poll() must not allocate).
const char* errno_text(int err) {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 32))
  const char* text = strerrordesc_np(err);
  return text != nullptr ? text : "Unknown error";
#else
  return std::strerror(err);
#endif
}

[[noreturn]] void fail(const std::string& device, std::string_view what, int err = 0) {
  std::string text = device;
  text += ": ";
  text += what;
  if (err != 0) {
    text += ": ";
    text += errno_text(err);
  }
  throw DeviceError(text);
}

// The key-capability bitmap (EVIOCGBIT(EV_KEY)); returns 0 or the ioctl's errno.
int read_key_bits(int fd, KeyBits& bits) {
  bits.fill(0);
  if (::ioctl(fd, EVIOCGBIT(EV_KEY, sizeof(bits)), bits.data()) < 0) return errno;
  return 0;
}

bool has_key(const KeyBits& bits, int code) {
  const auto c = static_cast<std::size_t>(code);
  return ((bits[c / kBitsPerLong] >> (c % kBitsPerLong)) & 1UL) != 0;
}

bool has_any_bound_key(const KeyBits& bits, std::span<const KeyBinding> bindings) {
  return std::any_of(bindings.begin(), bindings.end(),
                     [&](const KeyBinding& b) { return has_key(bits, b.code); });
}

// EVIOCGNAME, "" when the device reports none.
std::string read_device_name(int fd) {
  std::array<char, 256> name{};
  if (::ioctl(fd, EVIOCGNAME(name.size() - 1), name.data()) < 0) return {};
  return std::string(name.data());
}

bool contains_ignoring_case(std::string_view haystack, std::string_view needle) {
  const auto it = std::search(haystack.begin(), haystack.end(), needle.begin(), needle.end(),
                              [](char a, char b) {
                                return std::tolower(static_cast<unsigned char>(a)) ==
                                       std::tolower(static_cast<unsigned char>(b));
                              });
  return it != haystack.end() || needle.empty();
}

// The N of every /dev/input/eventN, ascending (event2 before event10).
std::vector<int> list_event_nodes(const std::string& spec) {
  DIR* dir = ::opendir(kInputDir);
  if (dir == nullptr) {
    const int err = errno;
    fail(spec, std::string("cannot list ") + kInputDir, err);
  }
  std::vector<int> numbers;
  while (const dirent* entry = ::readdir(dir)) {
    const std::string_view name(entry->d_name);
    if (!name.starts_with("event")) continue;
    const std::string_view digits = name.substr(5);
    int n = 0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
    if (ec == std::errc() && end == digits.data() + digits.size() && !digits.empty()) {
      numbers.push_back(n);
    }
  }
  ::closedir(dir);
  std::sort(numbers.begin(), numbers.end());
  return numbers;
}

struct Found {
  int fd = -1;
  std::string path;
};

// The first /dev/input/eventN whose name contains `needle` and which has a bound key.
Found find_by_name(const std::string& spec, std::string_view needle,
                   std::span<const KeyBinding> bindings) {
  const std::vector<int> nodes = list_event_nodes(spec);
  int unopenable = 0;
  int open_errno = 0;
  int named_without_keys = 0;
  for (const int n : nodes) {
    std::string path = std::string(kInputDir) + "/event" + std::to_string(n);
    const int fd = ::open(path.c_str(), kOpenFlags);
    if (fd < 0) {
      ++unopenable;
      if (open_errno == 0) open_errno = errno;
      continue;
    }
    if (contains_ignoring_case(read_device_name(fd), needle)) {
      KeyBits bits{};
      if (read_key_bits(fd, bits) == 0 && has_any_bound_key(bits, bindings)) {
        return Found{fd, std::move(path)};
      }
      ++named_without_keys;
    }
    ::close(fd);
  }
  std::string why = "no input device named like '" + printable(needle, 80) +
                    "' with reset/exit keys among " + kInputDir + "/event* (" +
                    std::to_string(nodes.size()) + " devices";
  if (named_without_keys > 0) {
    why += ", " + std::to_string(named_without_keys) + " named so without those keys";
  }
  if (unopenable > 0) {
    why += ", " + std::to_string(unopenable) + " could not be opened: " + errno_text(open_errno);
    if (open_errno == EACCES) why += " (is the user in group 'input'?)";
  }
  why += ")";
  fail(spec, why);
}

}  // namespace

const char* to_string(InputAction action) {
  switch (action) {
    case InputAction::kNone:
      return "none";
    case InputAction::kReset:
      return "reset";
    case InputAction::kExit:
      return "exit";
  }
  return "?";
}

EvdevKeys::EvdevKeys(std::string_view spec, bool grab, std::span<const KeyBinding> bindings)
    : spec_(spec) {
  set_bindings(bindings);
  if (spec.empty()) {
    throw DeviceError("input device: empty spec (want a /dev/input path or name:SUBSTRING)");
  }
  if (spec.starts_with(kNamePrefix)) {
    Found found = find_by_name(printable(spec, 200), spec.substr(kNamePrefix.size()), bindings_);
    fd_ = found.fd;
    path_ = std::move(found.path);
  } else {
    path_ = std::string(spec);
    fd_ = ::open(path_.c_str(), kOpenFlags);
    if (fd_ < 0) {
      const int err = errno;
      fail(printable(path_, 200), "cannot open input device", err);
    }
  }
  try {
    check_and_grab(grab);
  } catch (...) {
    close_fd();
    throw;
  }
}

EvdevKeys::EvdevKeys(int fd, std::string name, bool check_device, bool grab,
                     std::span<const KeyBinding> bindings)
    : fd_(fd), spec_(name), path_(std::move(name)) {
  try {
    set_bindings(bindings);
    if (fd_ < 0) fail(path_, "bad file descriptor");
    const int flags = ::fcntl(fd_, F_GETFL);
    if (flags < 0 || ::fcntl(fd_, F_SETFL, flags | O_NONBLOCK) < 0 ||
        ::fcntl(fd_, F_SETFD, FD_CLOEXEC) < 0) {
      const int err = errno;
      fail(path_, "fcntl", err);
    }
    if (check_device) check_and_grab(grab);
  } catch (...) {
    close_fd();
    throw;
  }
}

EvdevKeys::~EvdevKeys() { close_fd(); }

EvdevKeys::EvdevKeys(EvdevKeys&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      spec_(std::move(other.spec_)),
      path_(std::move(other.path_)),
      device_name_(std::move(other.device_name_)),
      bindings_(std::move(other.bindings_)),
      grabbed_(std::exchange(other.grabbed_, false)),
      lost_(other.lost_),
      counters_(other.counters_),
      buffered_(std::exchange(other.buffered_, 0)),
      buffer_(other.buffer_),
      last_error_(other.last_error_) {}

EvdevKeys& EvdevKeys::operator=(EvdevKeys&& other) noexcept {
  if (this != &other) {
    close_fd();
    fd_ = std::exchange(other.fd_, -1);
    spec_ = std::move(other.spec_);
    path_ = std::move(other.path_);
    device_name_ = std::move(other.device_name_);
    bindings_ = std::move(other.bindings_);
    grabbed_ = std::exchange(other.grabbed_, false);
    lost_ = other.lost_;
    counters_ = other.counters_;
    buffered_ = std::exchange(other.buffered_, 0);
    buffer_ = other.buffer_;
    last_error_ = other.last_error_;
  }
  return *this;
}

void EvdevKeys::set_bindings(std::span<const KeyBinding> bindings) {
  bindings_.clear();
  for (const KeyBinding& b : bindings) {
    if (b.code < 0 || b.code > KEY_MAX) {
      throw std::invalid_argument("evdev key binding: code " + std::to_string(b.code) +
                                  " outside 0.." + std::to_string(KEY_MAX));
    }
    // kNone binds nothing; for a code bound twice the first binding wins (in action_of).
    if (b.action != InputAction::kNone) bindings_.push_back(b);
  }
}

void EvdevKeys::check_and_grab(bool grab) {
  KeyBits bits{};
  if (const int err = read_key_bits(fd_, bits); err != 0) {
    fail(printable(path_, 200), "not an evdev device (EVIOCGBIT)", err);
  }
  device_name_ = read_device_name(fd_);
  if (!has_any_bound_key(bits, bindings_)) {
    fail(printable(path_, 200), "no reset/exit keys (not a keyboard?)");
  }
  if (grab) {
    if (::ioctl(fd_, EVIOCGRAB, 1) < 0) {
      const int err = errno;
      fail(printable(path_, 200), "cannot grab (EVIOCGRAB)", err);
    }
    grabbed_ = true;
  }
}

void EvdevKeys::close_fd() noexcept {
  if (fd_ >= 0) ::close(fd_);  // closing also releases an EVIOCGRAB
  fd_ = -1;
  grabbed_ = false;
}

InputAction EvdevKeys::poll(DurationNs timeout_ns) {
  if (lost_ || fd_ < 0) return InputAction::kNone;
  // Events read with the previous call's action come first.
  if (const InputAction action = decode(); action != InputAction::kNone) return action;

  const TimeNs deadline_ns = monotonic_now_ns() + std::max<DurationNs>(timeout_ns, 0);
  for (;;) {
    pollfd p{fd_, POLLIN, 0};
    const timespec ts = ns_to_timespec(std::max<DurationNs>(deadline_ns - monotonic_now_ns(), 0));
    const int n = ::ppoll(&p, 1, &ts, nullptr);
    if (n < 0) {
      if (errno == EINTR) continue;
      mark_lost("poll", errno);
      return InputAction::kNone;
    }
    if (n == 0) return InputAction::kNone;
    if ((p.revents & POLLNVAL) != 0) {
      mark_lost("poll", EBADF);
      return InputAction::kNone;
    }
    // POLLHUP/POLLERR: read anyway, for the events still queued and the real errno (ENODEV
    // from evdev after an unplug, end of stream from a pipe).
    const InputAction action = drain();
    if (action != InputAction::kNone || lost_) return action;
    if ((p.revents & POLLERR) != 0) {
      mark_lost("POLLERR", 0);
    } else if ((p.revents & POLLHUP) != 0) {
      mark_lost("POLLHUP", 0);
    }
    return InputAction::kNone;
  }
}

InputAction EvdevKeys::drain() {
  for (int reads = 0; reads < kMaxReadsPerPoll; ++reads) {
    // decode() leaves less than one event buffered, so there is always room.
    const ssize_t got = ::read(fd_, buffer_.data() + buffered_, buffer_.size() - buffered_);
    if (got < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return InputAction::kNone;
      mark_lost("read", errno);
      return InputAction::kNone;
    }
    if (got == 0) {
      mark_lost("end of stream", 0);
      return InputAction::kNone;
    }
    buffered_ += static_cast<std::size_t>(got);
    if (const InputAction action = decode(); action != InputAction::kNone) return action;
  }
  return InputAction::kNone;
}

InputAction EvdevKeys::decode() {
  std::size_t pos = 0;
  InputAction found = InputAction::kNone;
  while (found == InputAction::kNone && buffered_ - pos >= sizeof(input_event)) {
    input_event ev{};
    std::memcpy(&ev, buffer_.data() + pos, sizeof(ev));
    pos += sizeof(ev);
    ++counters_.events;
    if (ev.type == EV_SYN && ev.code == SYN_DROPPED) {
      ++counters_.dropped;
    } else if (ev.type == EV_KEY && ev.value == 1) {
      ++counters_.presses;
      for (const KeyBinding& b : bindings_) {
        if (b.code == ev.code) {
          found = b.action;
          break;
        }
      }
      if (found == InputAction::kNone) ++counters_.unbound_presses;
    }
  }
  if (pos > 0) {
    std::memmove(buffer_.data(), buffer_.data() + pos, buffered_ - pos);
    buffered_ -= pos;
  }
  return found;
}

void EvdevKeys::mark_lost(const char* what, int err) noexcept {
  lost_ = true;
  std::snprintf(last_error_.data(), last_error_.size(), "%s: device lost: %s%s%s", path_.c_str(),
                what, err != 0 ? ": " : "", err != 0 ? errno_text(err) : "");
}

}  // namespace wallar::drivers
