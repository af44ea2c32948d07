// SPDX-License-Identifier: Apache-2.0
/// @file uvc_reset.cpp
/// @brief USB port reset of a UVC camera picked by its video node.
#include "wallar/drivers/camera/uvc_reset.hpp"

#include <algorithm>
#include <exception>
#include <filesystem>

#include "wallar/drivers/usb/usb.hpp"

namespace wallar::drivers {

bool reset_uvc_camera(const std::string& usb_id, const std::string& device) {
  try {
    const UsbId id = parse_usb_id(usb_id, "camera usb_id");
    std::error_code ec;
    const std::string node = std::filesystem::canonical(device, ec).string();
    UsbContext usb;
    const std::vector<UsbDeviceInfo> devices = usb.enumerate(id);
    const UsbDeviceInfo* pick = nullptr;
    for (const UsbDeviceInfo& d : devices) {
      if (!node.empty() &&
          std::find(d.nodes.video.begin(), d.nodes.video.end(), node) != d.nodes.video.end())
        pick = &d;
    }
    if (pick == nullptr) {
      const auto bare = std::count_if(devices.begin(), devices.end(),
                                      [](const UsbDeviceInfo& d) { return d.nodes.video.empty(); });
      for (const UsbDeviceInfo& d : devices)
        if ((bare == 1 && d.nodes.video.empty()) || devices.size() == 1) pick = &d;
    }
    if (pick == nullptr) return false;
    (void)usb.reset_device(pick->bus, pick->ports);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace wallar::drivers
