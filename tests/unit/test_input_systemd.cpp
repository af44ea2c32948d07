// SPDX-License-Identifier: Apache-2.0
/// @file test_input_systemd.cpp
/// @brief EvdevKeys over a pipe (presses, releases, repeats, split events, hang-up), its
/// open errors, a real evdev device through uinput when /dev/uinput is usable, and
/// SystemdNotifier against a notify socket of our own (texts, watchdog pacing, no-op mode).
#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <linux/input.h>
#include <linux/uinput.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/core/time.hpp"
#include "wallar/drivers/input/evdev_keys.hpp"
#include "wallar/firmware/systemd_notify.hpp"

namespace wallar {
namespace {

using drivers::EvdevKeys;
using drivers::InputAction;
using drivers::KeyBinding;
using ::testing::HasSubstr;

constexpr DurationNs kWait = 1 * kNsPerS;  // for events already written: returns at once

input_event make_event(int type, int code, int value) {
  input_event ev{};
  ev.type = static_cast<std::uint16_t>(type);
  ev.code = static_cast<std::uint16_t>(code);
  ev.value = value;
  return ev;
}

// A pipe whose read end an EvdevKeys adopts (check_device=false); the test writes events.
class KeyPipe {
 public:
  KeyPipe() {
    std::array<int, 2> fds{-1, -1};
    if (::pipe2(fds.data(), O_CLOEXEC) != 0) ADD_FAILURE() << "pipe2: " << std::strerror(errno);
    write_fd_ = fds[1];
    keys_.emplace(fds[0], "pipe", /*check_device=*/false);
  }
  ~KeyPipe() { close_writer(); }
  KeyPipe(const KeyPipe&) = delete;
  KeyPipe& operator=(const KeyPipe&) = delete;

  EvdevKeys& keys() { return *keys_; }
  void write_bytes(const void* data, std::size_t n) {
    ASSERT_EQ(::write(write_fd_, data, n), static_cast<ssize_t>(n));
  }
  void write_events(const std::vector<input_event>& events) {
    write_bytes(events.data(), events.size() * sizeof(input_event));
  }
  // A key event followed by its SYN_REPORT, as the kernel sends it.
  void key(int code, int value) {
    write_events({make_event(EV_KEY, code, value), make_event(EV_SYN, SYN_REPORT, 0)});
  }
  void close_writer() {
    if (write_fd_ >= 0) ::close(write_fd_);
    write_fd_ = -1;
  }

 private:
  int write_fd_ = -1;
  std::optional<EvdevKeys> keys_;
};

TEST(EvdevKeys, DefaultBindings) {
  ASSERT_EQ(drivers::kDefaultKeyBindings.size(), 3U);
  EXPECT_EQ(drivers::kDefaultKeyBindings[0].code, KEY_R);
  EXPECT_EQ(drivers::kDefaultKeyBindings[0].action, InputAction::kReset);
  EXPECT_EQ(drivers::kDefaultKeyBindings[1].code, KEY_Q);
  EXPECT_EQ(drivers::kDefaultKeyBindings[1].action, InputAction::kExit);
  EXPECT_EQ(drivers::kDefaultKeyBindings[2].code, KEY_ESC);
  EXPECT_EQ(drivers::kDefaultKeyBindings[2].action, InputAction::kExit);
  EXPECT_STREQ(drivers::to_string(InputAction::kReset), "reset");
  EXPECT_STREQ(drivers::to_string(InputAction::kExit), "exit");
  EXPECT_STREQ(drivers::to_string(InputAction::kNone), "none");
}

TEST(EvdevKeys, PressOfRResets) {
  KeyPipe pipe;
  EXPECT_GE(pipe.keys().fd(), 0);
  pipe.key(KEY_R, 1);
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kReset);
  // The SYN_REPORT after the press stays buffered and is decoded by the next call.
  EXPECT_EQ(pipe.keys().poll(0), InputAction::kNone);
  EXPECT_EQ(pipe.keys().counters().events, 2U);
  EXPECT_EQ(pipe.keys().counters().presses, 1U);
  EXPECT_EQ(pipe.keys().counters().unbound_presses, 0U);
  EXPECT_FALSE(pipe.keys().lost());
  EXPECT_STREQ(pipe.keys().last_error(), "");
}

TEST(EvdevKeys, ReleaseAndRepeatDoNothing) {
  KeyPipe pipe;
  pipe.key(KEY_R, 0);  // release
  pipe.key(KEY_R, 2);  // auto-repeat
  pipe.key(KEY_Q, 2);
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kNone);
  EXPECT_EQ(pipe.keys().counters().events, 6U);
  EXPECT_EQ(pipe.keys().counters().presses, 0U);
  EXPECT_FALSE(pipe.keys().lost());
}

TEST(EvdevKeys, QAndEscExit) {
  KeyPipe pipe;
  pipe.key(KEY_Q, 1);
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kExit);
  pipe.key(KEY_Q, 0);
  pipe.key(KEY_ESC, 1);
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kExit);
  EXPECT_EQ(pipe.keys().counters().presses, 2U);
}

TEST(EvdevKeys, UnboundPressIsCounted) {
  KeyPipe pipe;
  pipe.key(KEY_A, 1);
  pipe.key(KEY_A, 0);
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kNone);
  EXPECT_EQ(pipe.keys().counters().presses, 1U);
  EXPECT_EQ(pipe.keys().counters().unbound_presses, 1U);
  EXPECT_EQ(pipe.keys().counters().events, 4U);
}

TEST(EvdevKeys, OtherEventTypesAreIgnored) {
  KeyPipe pipe;
  // A relative motion with value 1 and a misc scan code are not key presses.
  pipe.write_events({make_event(EV_REL, REL_X, 1), make_event(EV_MSC, MSC_SCAN, KEY_R),
                     make_event(EV_SYN, SYN_DROPPED, 0), make_event(EV_SYN, SYN_REPORT, 0)});
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kNone);
  EXPECT_EQ(pipe.keys().counters().events, 4U);
  EXPECT_EQ(pipe.keys().counters().presses, 0U);
  EXPECT_EQ(pipe.keys().counters().dropped, 1U);
}

TEST(EvdevKeys, EventSplitAcrossWritesIsDecoded) {
  KeyPipe pipe;
  const input_event press = make_event(EV_KEY, KEY_R, 1);
  const auto* bytes = reinterpret_cast<const unsigned char*>(&press);
  constexpr std::size_t kFirst = 5;
  pipe.write_bytes(bytes, kFirst);
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kNone);  // half an event: nothing yet
  EXPECT_EQ(pipe.keys().counters().events, 0U);
  pipe.write_bytes(bytes + kFirst, sizeof(press) - kFirst);
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kReset);
  EXPECT_EQ(pipe.keys().counters().events, 1U);
}

TEST(EvdevKeys, TwoPressesInOneReadAreBothSeen) {
  KeyPipe pipe;
  pipe.write_events({make_event(EV_KEY, KEY_R, 1), make_event(EV_SYN, SYN_REPORT, 0),
                     make_event(EV_KEY, KEY_ESC, 1), make_event(EV_SYN, SYN_REPORT, 0)});
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kReset);
  EXPECT_EQ(pipe.keys().poll(0), InputAction::kExit);
  EXPECT_EQ(pipe.keys().poll(0), InputAction::kNone);
  EXPECT_EQ(pipe.keys().counters().events, 4U);
}

TEST(EvdevKeys, ManyEventsBeyondOneBuffer) {
  KeyPipe pipe;
  std::vector<input_event> events;
  for (int i = 0; i < 300; ++i) {
    events.push_back(make_event(EV_KEY, KEY_A, 1));
    events.push_back(make_event(EV_KEY, KEY_A, 0));
  }
  events.push_back(make_event(EV_KEY, KEY_Q, 1));
  pipe.write_events(events);
  InputAction action = InputAction::kNone;
  for (int i = 0; i < 10 && action == InputAction::kNone; ++i) action = pipe.keys().poll(kWait);
  EXPECT_EQ(action, InputAction::kExit);
  EXPECT_EQ(pipe.keys().counters().unbound_presses, 300U);
  EXPECT_EQ(pipe.keys().counters().events, 601U);
}

TEST(EvdevKeys, TimeoutWithoutEvents) {
  KeyPipe pipe;
  const TimeNs t0 = monotonic_now_ns();
  EXPECT_EQ(pipe.keys().poll(30 * kNsPerMs), InputAction::kNone);
  const DurationNs waited = monotonic_now_ns() - t0;
  EXPECT_GE(waited, 29 * kNsPerMs);
  EXPECT_LT(waited, 2 * kNsPerS);
  EXPECT_EQ(pipe.keys().poll(0), InputAction::kNone);
  EXPECT_EQ(pipe.keys().poll(-5), InputAction::kNone);  // negative: no wait
  EXPECT_FALSE(pipe.keys().lost());
}

TEST(EvdevKeys, HangUpMakesItLost) {
  KeyPipe pipe;
  pipe.key(KEY_R, 1);
  pipe.close_writer();
  // Events queued before the hang-up are still delivered, then the loss is reported.
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kReset);
  EXPECT_FALSE(pipe.keys().lost());
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kNone);
  EXPECT_TRUE(pipe.keys().lost());
  const std::string message = pipe.keys().last_error();
  EXPECT_THAT(message, HasSubstr("pipe: device lost"));
  EXPECT_EQ(message.find('\n'), std::string::npos);
  // Further polls return at once.
  const TimeNs t0 = monotonic_now_ns();
  EXPECT_EQ(pipe.keys().poll(kWait), InputAction::kNone);
  EXPECT_LT(monotonic_now_ns() - t0, 100 * kNsPerMs);
  EXPECT_EQ(pipe.keys().spec(), "pipe");
}

TEST(EvdevKeys, CustomBindings) {
  std::array<int, 2> fds{-1, -1};
  ASSERT_EQ(::pipe2(fds.data(), O_CLOEXEC), 0);
  const std::array<KeyBinding, 2> bindings{
      {{KEY_SPACE, InputAction::kReset}, {KEY_R, InputAction::kNone}}};
  EvdevKeys keys(fds[0], "remote", false, false, bindings);
  const std::array<input_event, 2> events{make_event(EV_KEY, KEY_R, 1),
                                          make_event(EV_KEY, KEY_SPACE, 1)};
  ASSERT_EQ(::write(fds[1], events.data(), sizeof(events)), static_cast<ssize_t>(sizeof(events)));
  EXPECT_EQ(keys.poll(kWait), InputAction::kReset);
  EXPECT_EQ(keys.counters().unbound_presses, 1U);  // R bound to kNone = unbound
  ::close(fds[1]);
}

TEST(EvdevKeys, BindingOutOfRangeThrows) {
  std::array<int, 2> fds{-1, -1};
  ASSERT_EQ(::pipe2(fds.data(), O_CLOEXEC), 0);
  const std::array<KeyBinding, 1> bindings{{{KEY_MAX + 1, InputAction::kExit}}};
  EXPECT_THROW(EvdevKeys(fds[0], "pipe", false, false, bindings), std::invalid_argument);
  // The fd was adopted and closed even so.
  EXPECT_EQ(::fcntl(fds[0], F_GETFD), -1);
  ::close(fds[1]);
}

TEST(EvdevKeys, MoveKeepsTheDevice) {
  KeyPipe pipe;
  EvdevKeys moved = std::move(pipe.keys());
  EXPECT_EQ(pipe.keys().fd(), -1);  // NOLINT(bugprone-use-after-move): moved-from state
  EXPECT_EQ(pipe.keys().poll(0), InputAction::kNone);
  pipe.key(KEY_R, 1);
  EXPECT_EQ(moved.poll(kWait), InputAction::kReset);
}

template <typename F>
std::string device_error_of(F&& f) {
  try {
    f();
  } catch (const DeviceError& e) {
    return e.what();
  }
  return "(no DeviceError)";
}

TEST(EvdevKeys, MissingPathThrowsNamingIt) {
  const std::string message = device_error_of([] { EvdevKeys keys("/dev/input/event-nope-42"); });
  EXPECT_THAT(message, HasSubstr("/dev/input/event-nope-42"));
  EXPECT_THAT(message, HasSubstr("No such file or directory"));
  EXPECT_EQ(message.find('\n'), std::string::npos);
}

TEST(EvdevKeys, NameSearchWithoutMatchThrowsNamingIt) {
  const std::string message = device_error_of([] { EvdevKeys keys("name:no-such-keyboard"); });
  EXPECT_THAT(message, HasSubstr("name:no-such-keyboard"));
  EXPECT_EQ(message.find('\n'), std::string::npos);
}

TEST(EvdevKeys, EmptySpecThrows) {
  EXPECT_THAT(device_error_of([] { EvdevKeys keys(""); }), HasSubstr("empty spec"));
}

TEST(EvdevKeys, CheckedNonEvdevFdThrows) {
  std::array<int, 2> fds{-1, -1};
  ASSERT_EQ(::pipe2(fds.data(), O_CLOEXEC), 0);
  const std::string message =
      device_error_of([&] { EvdevKeys keys(fds[0], "not-evdev", /*check_device=*/true); });
  EXPECT_THAT(message, HasSubstr("not-evdev: not an evdev device (EVIOCGBIT)"));
  EXPECT_EQ(::fcntl(fds[0], F_GETFD), -1);  // closed
  ::close(fds[1]);
  EXPECT_THAT(device_error_of([] { EvdevKeys keys(-1, "nothing", false); }),
              HasSubstr("nothing: bad file descriptor"));
}

// A virtual keyboard through uinput: the real kernel path (EVIOCGNAME search, EVIOCGBIT,
// EVIOCGRAB, ENODEV on removal). Skipped where /dev/uinput is missing or not writable.
class UinputKeyboard {
 public:
  explicit UinputKeyboard(const std::string& name, bool with_bound_keys) {
    fd_ = ::open("/dev/uinput", O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) return;
    ::ioctl(fd_, UI_SET_EVBIT, EV_KEY);
    ::ioctl(fd_, UI_SET_KEYBIT, KEY_A);
    if (with_bound_keys) {
      ::ioctl(fd_, UI_SET_KEYBIT, KEY_R);
      ::ioctl(fd_, UI_SET_KEYBIT, KEY_Q);
    }
    uinput_setup setup{};
    setup.id.bustype = BUS_VIRTUAL;
    setup.id.vendor = 0x1209;
    setup.id.product = 0x0001;
    std::snprintf(setup.name, sizeof(setup.name), "%s", name.c_str());
    if (::ioctl(fd_, UI_DEV_SETUP, &setup) < 0 || ::ioctl(fd_, UI_DEV_CREATE) < 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~UinputKeyboard() { destroy(); }
  UinputKeyboard(const UinputKeyboard&) = delete;
  UinputKeyboard& operator=(const UinputKeyboard&) = delete;

  [[nodiscard]] bool ok() const { return fd_ >= 0; }
  void emit(int type, int code, int value) {
    const input_event ev = make_event(type, code, value);
    ASSERT_EQ(::write(fd_, &ev, sizeof(ev)), static_cast<ssize_t>(sizeof(ev)));
  }
  void destroy() {
    if (fd_ < 0) return;
    ::ioctl(fd_, UI_DEV_DESTROY);
    ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
};

// The event node appears shortly after UI_DEV_CREATE: retry the search for a while. On
// failure `error` holds the last message.
std::optional<EvdevKeys> open_when_present(const std::string& spec, bool grab, std::string& error) {
  for (int attempt = 0; attempt < 100; ++attempt) {
    try {
      return EvdevKeys(spec, grab);
    } catch (const DeviceError& e) {
      error = e.what();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  return std::nullopt;
}

TEST(EvdevKeys, UinputKeyboardByName) {
  const std::string name = "wallar-test-keys-" + std::to_string(::getpid());
  UinputKeyboard keyboard(name, true);
  if (!keyboard.ok()) GTEST_SKIP() << "/dev/uinput not usable here";
  std::string error;
  std::optional<EvdevKeys> keys = open_when_present("name:" + name, /*grab=*/true, error);
  if (!keys && error.find("Permission denied") != std::string::npos) {
    GTEST_SKIP() << "uinput writable but /dev/input/event* not readable: " << error;
  }
  ASSERT_TRUE(keys.has_value()) << error;
  EXPECT_EQ(keys->device_name(), name);
  EXPECT_TRUE(keys->grabbed());
  EXPECT_THAT(keys->path(), HasSubstr("/dev/input/event"));
  keyboard.emit(EV_KEY, KEY_R, 1);
  keyboard.emit(EV_SYN, SYN_REPORT, 0);
  EXPECT_EQ(keys->poll(kWait), InputAction::kReset);
  keyboard.emit(EV_KEY, KEY_R, 0);
  keyboard.emit(EV_SYN, SYN_REPORT, 0);
  EXPECT_EQ(keys->poll(kWait), InputAction::kNone);
  keyboard.destroy();
  InputAction action = InputAction::kNone;
  for (int i = 0; i < 5 && !keys->lost(); ++i) action = keys->poll(kWait);
  EXPECT_EQ(action, InputAction::kNone);
  EXPECT_TRUE(keys->lost());
  EXPECT_THAT(keys->last_error(), HasSubstr(keys->path() + ": device lost"));
}

TEST(EvdevKeys, UinputDeviceWithoutBoundKeysIsRefused) {
  const std::string name = "wallar-test-pad-" + std::to_string(::getpid());
  UinputKeyboard pad(name, false);
  if (!pad.ok()) GTEST_SKIP() << "/dev/uinput not usable here";
  // Found by name but without R/Q/Esc: the search goes on and fails naming what it saw.
  std::string message;
  for (int attempt = 0; attempt < 100; ++attempt) {
    message = device_error_of([&] { EvdevKeys keys("name:" + name); });
    if (message.find("named so without those keys") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_THAT(message, HasSubstr("name:" + name));
  EXPECT_THAT(message, HasSubstr("1 named so without those keys"));
}

// Sets environment variables for one test and restores the previous values after it.
class EnvGuard {
 public:
  EnvGuard() {
    for (const char* name : kNames) {
      const char* value = std::getenv(name);
      saved_.push_back(value != nullptr ? std::optional<std::string>(value) : std::nullopt);
    }
  }
  ~EnvGuard() {
    for (std::size_t i = 0; i < kNames.size(); ++i) {
      if (saved_[i]) {
        ::setenv(kNames[i], saved_[i]->c_str(), 1);
      } else {
        ::unsetenv(kNames[i]);
      }
    }
  }
  EnvGuard(const EnvGuard&) = delete;
  EnvGuard& operator=(const EnvGuard&) = delete;
  void set(const char* name, const std::string& value) { ::setenv(name, value.c_str(), 1); }
  void unset(const char* name) { ::unsetenv(name); }

 private:
  static constexpr std::array<const char*, 3> kNames{"NOTIFY_SOCKET", "WATCHDOG_USEC",
                                                     "WATCHDOG_PID"};
  std::vector<std::optional<std::string>> saved_;
};

// A datagram socket bound at a temporary path, standing in for systemd's notify socket.
class NotifySocket {
 public:
  NotifySocket() {
    static int counter = 0;
    path_ = "/tmp/wallar_notify_" + std::to_string(::getpid()) + "_" + std::to_string(counter++);
    ::unlink(path_.c_str());
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", path_.c_str());
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
      ADD_FAILURE() << "notify socket " << path_ << ": " << std::strerror(errno);
    }
  }
  ~NotifySocket() {
    ::close(fd_);
    ::unlink(path_.c_str());
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;
  [[nodiscard]] const std::string& path() const { return path_; }

  // Every datagram queued so far.
  std::vector<std::string> receive_all() {
    std::vector<std::string> out;
    std::array<char, 4096> buf{};
    for (;;) {
      const ssize_t n = ::recv(fd_, buf.data(), buf.size(), MSG_DONTWAIT);
      if (n < 0) break;
      out.emplace_back(buf.data(), static_cast<std::size_t>(n));
    }
    return out;
  }

 private:
  std::string path_;
  int fd_ = -1;
};

TEST(SystemdNotifier, SendsStatesAndPacesTheWatchdog) {
  EnvGuard env;
  NotifySocket socket;
  env.set("NOTIFY_SOCKET", socket.path());
  env.set("WATCHDOG_USEC", "200000");
  env.set("WATCHDOG_PID", std::to_string(::getpid()));

  firmware::SystemdNotifier notifier;
  EXPECT_TRUE(notifier.active());
  EXPECT_EQ(notifier.watchdog_period_ns(), 200 * kNsPerMs);

  const TimeNs now = monotonic_now_ns();
  notifier.ready();
  notifier.status("x");
  EXPECT_TRUE(notifier.watchdog_due(now));
  notifier.watchdog(now);
  EXPECT_FALSE(notifier.watchdog_due(now + kNsPerMs));
  notifier.watchdog(now + kNsPerMs);  // suppressed: within half the period
  EXPECT_FALSE(notifier.watchdog_due(now + 99 * kNsPerMs));
  EXPECT_TRUE(notifier.watchdog_due(now + 150 * kNsPerMs));
  notifier.watchdog(now + 150 * kNsPerMs);
  notifier.stopping();

  const std::vector<std::string> got = socket.receive_all();
  EXPECT_THAT(
      got, ::testing::ElementsAre("READY=1", "STATUS=x", "WATCHDOG=1", "WATCHDOG=1", "STOPPING=1"));
  EXPECT_EQ(notifier.sent(), 5U);
  EXPECT_EQ(notifier.errors(), 0U);
  // The environment is left for whoever reads it next.
  EXPECT_NE(std::getenv("NOTIFY_SOCKET"), nullptr);
  EXPECT_NE(std::getenv("WATCHDOG_USEC"), nullptr);
}

TEST(SystemdNotifier, TriggerAndStatusSanitizing) {
  EnvGuard env;
  NotifySocket socket;
  env.set("NOTIFY_SOCKET", socket.path());
  env.unset("WATCHDOG_USEC");
  env.unset("WATCHDOG_PID");

  firmware::SystemdNotifier notifier;
  EXPECT_TRUE(notifier.active());
  EXPECT_EQ(notifier.watchdog_period_ns(), 0);
  EXPECT_FALSE(notifier.watchdog_due(monotonic_now_ns()));
  notifier.watchdog(monotonic_now_ns());  // no watchdog configured: nothing sent
  notifier.status("tracking\nWATCHDOG=trigger");
  notifier.status(nullptr);
  notifier.status(std::string(1000, 'a').c_str());
  notifier.watchdog_trigger();

  const std::vector<std::string> got = socket.receive_all();
  ASSERT_EQ(got.size(), 4U);
  EXPECT_EQ(got[0], "STATUS=tracking WATCHDOG=trigger");  // one assignment, not two
  EXPECT_EQ(got[1], "STATUS=");
  EXPECT_EQ(got[2], "STATUS=" + std::string(firmware::SystemdNotifier::kMaxStatusChars, 'a'));
  EXPECT_EQ(got[3], "WATCHDOG=trigger");
}

TEST(SystemdNotifier, WatchdogForAnotherPidIsOff) {
  EnvGuard env;
  NotifySocket socket;
  env.set("NOTIFY_SOCKET", socket.path());
  env.set("WATCHDOG_USEC", "200000");
  env.set("WATCHDOG_PID", std::to_string(::getpid() + 1));
  firmware::SystemdNotifier notifier;
  EXPECT_TRUE(notifier.active());
  EXPECT_EQ(notifier.watchdog_period_ns(), 0);
}

TEST(SystemdNotifier, WithoutNotifySocketEverythingIsANoOp) {
  EnvGuard env;
  env.unset("NOTIFY_SOCKET");
  env.set("WATCHDOG_USEC", "200000");
  env.set("WATCHDOG_PID", std::to_string(::getpid()));
  firmware::SystemdNotifier notifier;
  EXPECT_FALSE(notifier.active());
  EXPECT_EQ(notifier.watchdog_period_ns(), 0);
  const TimeNs now = monotonic_now_ns();
  EXPECT_FALSE(notifier.watchdog_due(now));
  notifier.ready();
  notifier.status("x");
  notifier.watchdog(now);
  notifier.watchdog_trigger();
  notifier.stopping();
  EXPECT_EQ(notifier.sent(), 0U);
  EXPECT_EQ(notifier.errors(), 0U);
}

TEST(SystemdNotifier, UnreachableSocketCountsErrors) {
  EnvGuard env;
  env.set("NOTIFY_SOCKET", "/tmp/wallar_notify_nobody_listens_" + std::to_string(::getpid()));
  env.unset("WATCHDOG_USEC");
  firmware::SystemdNotifier notifier;
  EXPECT_TRUE(notifier.active());
  notifier.ready();
  EXPECT_EQ(notifier.sent(), 0U);
  EXPECT_EQ(notifier.errors(), 1U);
  EXPECT_NE(notifier.last_errno(), 0);
}

}  // namespace
}  // namespace wallar
