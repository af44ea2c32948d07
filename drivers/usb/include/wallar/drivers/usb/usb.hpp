// SPDX-License-Identifier: Apache-2.0
/// @file usb.hpp
/// @brief USB device discovery by "VID:PID" (libusb-1.0), the bus/port path, the device
/// nodes a kernel driver made for it (sysfs), hot-plug callbacks and device reset.
///
/// Board files name devices by USB id (`usb_id: "32e4:9750"`); two identical cameras differ
/// only by the port they are plugged into, so every device found carries its bus and port
/// path ("1-1.2", the sysfs name) and the /dev nodes found under it in sysfs
/// (/dev/ttyUSB*, /dev/ttyACM*, /dev/video*).
///
/// Nothing here is on a fixed-rate path: everything may allocate and throws UsbError on
/// failure (one line naming the operation and libusb's error name).
///
/// Threading: a UsbContext and its hot-plug registrations belong to one thread; callbacks
/// run on the thread that calls handle_events(). Free functions are thread-safe.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "wallar/core/error.hpp"
#include "wallar/core/time.hpp"

struct libusb_context;

namespace wallar::drivers {

/// libusb could not be initialised or an operation on a device failed.
class UsbError : public DeviceError {
 public:
  using DeviceError::DeviceError;
};

struct UsbId {
  std::uint16_t vid = 0;
  std::uint16_t pid = 0;
  friend bool operator==(const UsbId&, const UsbId&) = default;
};

/// Parses "32e4:9750" (four hex digits each side, either case). Bad input throws InputError
/// "<where>: bad USB id '<text>' (want VID:PID, four hex digits each, e.g. 32e4:9750)".
UsbId parse_usb_id(std::string_view text, std::string_view where = "usb_id");
/// "32e4:9750".
std::string format_usb_id(UsbId id);

/// The /dev nodes a kernel driver created for a device's interfaces.
struct UsbDeviceNodes {
  std::vector<std::string> tty;    //!< /dev/ttyUSB* (usb-serial), /dev/ttyACM* (cdc-acm)
  std::vector<std::string> video;  //!< /dev/video* (uvcvideo)
};

struct UsbDeviceInfo {
  UsbId id;
  std::uint8_t bus = 0;
  std::uint8_t address = 0;
  std::vector<std::uint8_t> ports;  //!< port numbers from the root hub down
  UsbDeviceNodes nodes;
  /// The sysfs/kernel name: "<bus>-<port>.<port>..." ("1-1.2"), "usb<bus>" for a root hub.
  [[nodiscard]] std::string port_path() const;
};

/// The sysfs name of a device: "1-1.2" for bus 1, ports {1, 2}; "usb1" for the root hub.
std::string usb_port_path(std::uint8_t bus, const std::vector<std::uint8_t>& ports);

/// The device nodes under /sys/bus/usb/devices/<port_path>'s interfaces ("<port_path>:C.I"):
/// ttyUSB* (usb-serial puts it directly in the interface), tty/ttyACM* (cdc-acm) and
/// video4linux/video*. Sorted; empty when sysfs has nothing (no driver bound, no sysfs).
/// `sysfs_usb_devices` is a parameter so tests can build a fake tree.
UsbDeviceNodes find_device_nodes(
    std::string_view port_path,
    const std::filesystem::path& sysfs_usb_devices = "/sys/bus/usb/devices");

/// A hot-plug event: the device (nodes usually empty on arrival: the kernel driver binds
/// after libusb's event) and whether it arrived (true) or left (false).
using UsbHotplugCallback = std::function<void(const UsbDeviceInfo& device, bool arrived)>;

/// A libusb context (RAII).
class UsbContext {
 public:
  /// Throws UsbError "libusb: init: LIBUSB_ERROR_... (...)" when libusb cannot start (no
  /// usbfs, as in a container without /dev/bus/usb).
  UsbContext();
  ~UsbContext();
  UsbContext(const UsbContext&) = delete;
  UsbContext& operator=(const UsbContext&) = delete;

  /// Devices matching `filter` (all when nullopt), in bus/port order, with their nodes.
  std::vector<UsbDeviceInfo> enumerate(std::optional<UsbId> filter = std::nullopt);

  /// True when this libusb and platform deliver hot-plug events.
  [[nodiscard]] bool has_hotplug() const;

  /// Calls `callback` for arrivals and departures of devices with `id` (enumerate=true also
  /// reports the devices already present as arrivals). Returns a handle; the registration
  /// ends when it is destroyed. Throws UsbError when hot-plug is unsupported.
  class HotplugRegistration;
  std::unique_ptr<HotplugRegistration> register_hotplug(UsbId id, UsbHotplugCallback callback,
                                                        bool enumerate = false);

  /// Processes pending libusb events (hot-plug callbacks run here), waiting up to timeout.
  void handle_events(DurationNs timeout_ns);

  /// Resets the device at bus/port path (libusb_reset_device: a port reset, as after a stall).
  /// Returns true when the device is back at the same address, false when it re-enumerated
  /// (it must be looked up again). Throws UsbError when it is not found or cannot be reset.
  bool reset_device(std::uint8_t bus, const std::vector<std::uint8_t>& ports);

 private:
  libusb_context* ctx_ = nullptr;
};

class UsbContext::HotplugRegistration {
 public:
  HotplugRegistration(libusb_context* ctx, UsbHotplugCallback callback);
  ~HotplugRegistration();
  HotplugRegistration(const HotplugRegistration&) = delete;
  HotplugRegistration& operator=(const HotplugRegistration&) = delete;
  void set_handle(int handle) { handle_ = handle; }
  void deliver(const UsbDeviceInfo& device, bool arrived) { callback_(device, arrived); }

 private:
  libusb_context* ctx_;
  UsbHotplugCallback callback_;
  int handle_ = -1;
};

}  // namespace wallar::drivers
