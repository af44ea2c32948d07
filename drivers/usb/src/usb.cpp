// SPDX-License-Identifier: Apache-2.0
/// @file usb.cpp
/// @brief libusb-1.0 enumeration, hot-plug and reset; sysfs lookup of the device nodes.
#include "wallar/drivers/usb/usb.hpp"

#include <libusb.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <system_error>

#include "wallar/core/error.hpp"

namespace wallar::drivers {
namespace {

[[noreturn]] void throw_usb(std::string_view what, int err) {
  std::string msg = "libusb: ";
  msg += what;
  msg += ": ";
  msg += libusb_error_name(err);
  msg += " (";
  msg += libusb_strerror(static_cast<libusb_error>(err));
  msg += ")";
  throw UsbError(msg);
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::optional<std::uint16_t> parse_hex4(std::string_view s) {
  if (s.size() != 4) return std::nullopt;
  unsigned v = 0;
  for (char c : s) {
    const int d = hex_digit(c);
    if (d < 0) return std::nullopt;
    v = (v << 4) | static_cast<unsigned>(d);
  }
  return static_cast<std::uint16_t>(v);
}

std::vector<std::uint8_t> port_numbers(libusb_device* dev) {
  std::array<std::uint8_t, 8> ports{};  // USB 3 allows a depth of 7
  const int n = libusb_get_port_numbers(dev, ports.data(), static_cast<int>(ports.size()));
  if (n <= 0) return {};
  return {ports.begin(), ports.begin() + n};
}

std::optional<UsbDeviceInfo> describe(libusb_device* dev, std::optional<UsbId> filter) {
  libusb_device_descriptor desc{};
  if (libusb_get_device_descriptor(dev, &desc) != LIBUSB_SUCCESS) return std::nullopt;
  const UsbId id{desc.idVendor, desc.idProduct};
  if (filter && !(*filter == id)) return std::nullopt;
  UsbDeviceInfo info;
  info.id = id;
  info.bus = libusb_get_bus_number(dev);
  info.address = libusb_get_device_address(dev);
  info.ports = port_numbers(dev);
  return info;
}

// Entries of dir whose names start with prefix, sorted; nothing if dir is unreadable.
std::vector<std::filesystem::path> entries_with_prefix(const std::filesystem::path& dir,
                                                       std::string_view prefix) {
  std::vector<std::filesystem::path> out;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) == 0) out.push_back(it->path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

int hotplug_trampoline(libusb_context* /*ctx*/, libusb_device* dev, libusb_hotplug_event event,
                       void* user) {
  auto* reg = static_cast<UsbContext::HotplugRegistration*>(user);
  if (std::optional<UsbDeviceInfo> info = describe(dev, std::nullopt)) {
    if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED) {
      info->nodes = find_device_nodes(info->port_path());
    }
    try {
      reg->deliver(*info, event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED);
    } catch (...) {
      // An exception must not unwind through libusb's C frames; the callback owns its errors.
    }
  }
  return 0;  // stay registered
}

}  // namespace

UsbId parse_usb_id(std::string_view text, std::string_view where) {
  const std::size_t colon = text.find(':');
  std::optional<std::uint16_t> vid, pid;
  if (colon != std::string_view::npos) {
    vid = parse_hex4(text.substr(0, colon));
    pid = parse_hex4(text.substr(colon + 1));
  }
  if (!vid || !pid) {
    throw_input_error(where, 0,
                      "bad USB id '" + printable(text) +
                          "' (want VID:PID, four hex digits each, e.g. 32e4:9750)");
  }
  return {*vid, *pid};
}

std::string format_usb_id(UsbId id) {
  constexpr char kHex[] = "0123456789abcdef";
  std::string s(9, ':');
  for (int i = 0; i < 4; ++i) {
    s[3 - i] = kHex[(id.vid >> (4 * i)) & 0xF];
    s[8 - i] = kHex[(id.pid >> (4 * i)) & 0xF];
  }
  return s;
}

std::string usb_port_path(std::uint8_t bus, const std::vector<std::uint8_t>& ports) {
  if (ports.empty()) return "usb" + std::to_string(bus);
  std::string s = std::to_string(bus) + "-";
  for (std::size_t i = 0; i < ports.size(); ++i) {
    if (i > 0) s += '.';
    s += std::to_string(ports[i]);
  }
  return s;
}

std::string UsbDeviceInfo::port_path() const { return usb_port_path(bus, ports); }

UsbDeviceNodes find_device_nodes(std::string_view port_path,
                                 const std::filesystem::path& sysfs_usb_devices) {
  UsbDeviceNodes nodes;
  const std::filesystem::path dev_dir = sysfs_usb_devices / std::string(port_path);
  // Interfaces are subdirectories "<port_path>:<config>.<interface>".
  for (const auto& intf : entries_with_prefix(dev_dir, std::string(port_path) + ":")) {
    for (const auto& p : entries_with_prefix(intf, "ttyUSB")) {
      nodes.tty.push_back("/dev/" + p.filename().string());
    }
    for (const auto& p : entries_with_prefix(intf / "tty", "tty")) {
      nodes.tty.push_back("/dev/" + p.filename().string());
    }
    for (const auto& p : entries_with_prefix(intf / "video4linux", "video")) {
      nodes.video.push_back("/dev/" + p.filename().string());
    }
  }
  std::sort(nodes.tty.begin(), nodes.tty.end());
  std::sort(nodes.video.begin(), nodes.video.end());
  return nodes;
}

UsbContext::UsbContext() {
  const int err = libusb_init(&ctx_);
  if (err != LIBUSB_SUCCESS) {
    ctx_ = nullptr;
    throw_usb("init", err);
  }
}

UsbContext::~UsbContext() {
  if (ctx_ != nullptr) libusb_exit(ctx_);
}

std::vector<UsbDeviceInfo> UsbContext::enumerate(std::optional<UsbId> filter) {
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx_, &list);
  if (n < 0) throw_usb("get_device_list", static_cast<int>(n));
  std::vector<UsbDeviceInfo> out;
  for (ssize_t i = 0; i < n; ++i) {
    if (std::optional<UsbDeviceInfo> info = describe(list[i], filter)) {
      info->nodes = find_device_nodes(info->port_path());
      out.push_back(std::move(*info));
    }
  }
  libusb_free_device_list(list, 1);
  std::sort(out.begin(), out.end(), [](const UsbDeviceInfo& a, const UsbDeviceInfo& b) {
    return a.bus != b.bus ? a.bus < b.bus : a.ports < b.ports;
  });
  return out;
}

bool UsbContext::has_hotplug() const { return libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0; }

UsbContext::HotplugRegistration::HotplugRegistration(libusb_context* ctx,
                                                     UsbHotplugCallback callback)
    : ctx_(ctx), callback_(std::move(callback)) {}

UsbContext::HotplugRegistration::~HotplugRegistration() {
  if (handle_ >= 0) libusb_hotplug_deregister_callback(ctx_, handle_);
}

std::unique_ptr<UsbContext::HotplugRegistration> UsbContext::register_hotplug(
    UsbId id, UsbHotplugCallback callback, bool enumerate) {
  if (!has_hotplug()) throw_usb("hotplug", LIBUSB_ERROR_NOT_SUPPORTED);
  auto reg = std::make_unique<HotplugRegistration>(ctx_, std::move(callback));
  libusb_hotplug_callback_handle handle = 0;
  const int events = LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT;
  const int err = libusb_hotplug_register_callback(
      ctx_, events, enumerate ? LIBUSB_HOTPLUG_ENUMERATE : 0, id.vid, id.pid,
      LIBUSB_HOTPLUG_MATCH_ANY, hotplug_trampoline, reg.get(), &handle);
  if (err != LIBUSB_SUCCESS) throw_usb("hotplug_register_callback " + format_usb_id(id), err);
  reg->set_handle(handle);
  return reg;
}

void UsbContext::handle_events(DurationNs timeout_ns) {
  timeval tv{static_cast<time_t>(timeout_ns / kNsPerS),
             static_cast<suseconds_t>((timeout_ns % kNsPerS) / kNsPerUs)};
  const int err = libusb_handle_events_timeout_completed(ctx_, &tv, nullptr);
  if (err != LIBUSB_SUCCESS && err != LIBUSB_ERROR_INTERRUPTED) throw_usb("handle_events", err);
}

bool UsbContext::reset_device(std::uint8_t bus, const std::vector<std::uint8_t>& ports) {
  const std::string where = "reset " + usb_port_path(bus, ports);
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx_, &list);
  if (n < 0) throw_usb(where, static_cast<int>(n));
  libusb_device* found = nullptr;
  for (ssize_t i = 0; i < n && found == nullptr; ++i) {
    if (libusb_get_bus_number(list[i]) == bus && port_numbers(list[i]) == ports) found = list[i];
  }
  if (found == nullptr) {
    libusb_free_device_list(list, 1);
    throw_usb(where, LIBUSB_ERROR_NO_DEVICE);
  }
  libusb_device_handle* h = nullptr;
  int err = libusb_open(found, &h);
  libusb_free_device_list(list, 1);
  if (err != LIBUSB_SUCCESS) throw_usb(where + ": open", err);
  err = libusb_reset_device(h);
  libusb_close(h);
  if (err == LIBUSB_ERROR_NOT_FOUND) return false;  // re-enumerated: look it up again
  if (err != LIBUSB_SUCCESS) throw_usb(where, err);
  return true;
}

}  // namespace wallar::drivers
