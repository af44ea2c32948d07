// SPDX-License-Identifier: Apache-2.0
/// @file device_names.hpp
/// @brief Stable device names resolved against a device tree: GPIO chips by label, and the
/// udev links (/dev/v4l/by-id, /dev/v4l/by-path, /dev/dri/by-path, /dev/input/by-id) by
/// following them, so a board file never depends on probe order.
///
/// A GPIO chip is named as libgpiod's lookup takes it: a path ("/dev/gpiochip0"), a name
/// ("gpiochip0"), a number ("0"), or anything else as the chip's label ("pinctrl-rp1": the
/// Raspberry Pi 5's header chip, gpiochip0 on kernels since 6.6.45 and gpiochip4 before).
/// Labels are read with GPIO_GET_CHIPINFO_IOCTL from each /dev/gpiochipN, as libgpiod does.
///
/// The tree's root is "/" on a device; tests (and a check of a headset's image mounted
/// elsewhere) give a folder holding dev/, and a chip-info reader of their own, because a
/// regular file cannot answer the GPIO ioctl.
///
/// Nothing here is on a fixed-rate path: it runs before any thread starts and may allocate.
/// Failures throw DeviceError with one line naming the name and what was found instead.
///
/// Threading: a DeviceTree is immutable; its functions may be called from any thread.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace wallar::drivers {

/// What GPIO_GET_CHIPINFO_IOCTL says about a chip.
struct GpioChipInfo {
  std::string name;   //!< "gpiochip0"
  std::string label;  //!< "pinctrl-rp1"
  unsigned lines = 0;
};

/// Reads a chip's info from its node (a path under the tree's root); nullopt when the node is
/// not a GPIO chip or cannot be opened (errno says why).
using GpioChipInfoReader = std::function<std::optional<GpioChipInfo>(const std::filesystem::path&)>;

/// The kernel's answer: opens the node and asks GPIO_GET_CHIPINFO_IOCTL.
std::optional<GpioChipInfo> read_gpio_chip_info(const std::filesystem::path& node);

/// For a tree copied from a board or made by a test (`wallar run --check --root DIR`): a node
/// that is a character device is asked as above; any other file named gpiochipN is described by
/// the kernel's sysfs under the same root, sys/bus/gpio/devices/gpiochipN/gpio/gpiochip*/label
/// and ngpio (the legacy GPIO class every Debian and Raspberry Pi kernel builds).
GpioChipInfoReader gpio_chip_info_in(const std::filesystem::path& root);

class DeviceTree {
 public:
  explicit DeviceTree(std::filesystem::path root = "/",
                      GpioChipInfoReader chip_info = read_gpio_chip_info);

  [[nodiscard]] const std::filesystem::path& root() const { return root_; }
  [[nodiscard]] bool is_system() const { return root_ == "/"; }
  /// Where an absolute device path ("/dev/video0") is in this tree.
  [[nodiscard]] std::filesystem::path host_path(const std::filesystem::path& device_path) const;
  /// The tree's own path for a host path under its root ("/dev/video0"); `host` unchanged
  /// when it is not under the root.
  [[nodiscard]] std::filesystem::path device_path(const std::filesystem::path& host) const;
  [[nodiscard]] std::optional<GpioChipInfo> chip_info(const std::filesystem::path& node) const {
    return chip_info_(host_path(node));
  }

 private:
  std::filesystem::path root_;
  GpioChipInfoReader chip_info_;
};

/// A device path followed through its links: `path` as named, `node` the file it ends at
/// ("/dev/v4l/by-path/...-video-index0" -> "/dev/video2"), both in the tree's own paths.
struct ResolvedNode {
  std::string path;
  std::string node;
  /// "/dev/video2", or "by-path/...-video-index0 -> /dev/video2" when it is a link.
  [[nodiscard]] std::string describe() const;
};

/// Follows `path` (absolute) through its links. Throws DeviceError "PATH: no such device"
/// (with the entries of its udev link folder, by-path or by-id, when that exists, so a camera
/// on the other port is visible), or
/// "PATH: not a device node" when it ends at a folder.
ResolvedNode resolve_device_node(std::string_view path, const DeviceTree& tree);

/// A GPIO chip found by path, name, number or label.
struct ResolvedGpioChip {
  std::string spec;  //!< as named
  std::string path;  //!< "/dev/gpiochip0"
  GpioChipInfo info;
  [[nodiscard]] std::string describe() const;  //!< "pinctrl-rp1 -> /dev/gpiochip0 (54 lines)"
};

/// Finds the chip. A label must match exactly one chip. Throws DeviceError naming the spec and
/// the chips present ("'pinctrl-rp1': no GPIO chip has that label (gpiochip0 'pinctrl-bcm2712'
/// 32 lines, ...)"), or "no GPIO chips under /dev".
ResolvedGpioChip resolve_gpio_chip(std::string_view spec, const DeviceTree& tree);

}  // namespace wallar::drivers
