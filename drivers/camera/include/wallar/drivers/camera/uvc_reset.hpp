// SPDX-License-Identifier: Apache-2.0
/// @file uvc_reset.hpp
/// @brief The last rung of the camera recovery ladder on real hardware: a USB port reset of a
/// UVC camera through libusb.
///
/// Two cameras of one model share a VID:PID, so the device is picked by its video node: the
/// USB device with `usb_id` whose interface owns `device` (symlinks such as
/// /dev/v4l/by-path/... resolved). When the node is already gone (the camera fell off the bus
/// and came back without a driver), the one device with that id that has no video node is
/// reset, or the only device with that id.
///
/// Threading: any thread; each call opens its own libusb context.
#pragma once

#include <string>

namespace wallar::drivers {

/// Resets the camera's USB port; false (never throws) when no such device is found or libusb
/// cannot reset it (no usbfs access, as in containers).
bool reset_uvc_camera(const std::string& usb_id, const std::string& device);

}  // namespace wallar::drivers
