// SPDX-License-Identifier: Apache-2.0
/// @file device_names.cpp
/// @brief GPIO chips by label (GPIO_GET_CHIPINFO_IOCTL) and udev links followed to their nodes.
#include "wallar/drivers/devices/device_names.hpp"

#include <fcntl.h>
#include <linux/gpio.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>
#include <vector>

#include "wallar/core/error.hpp"

namespace wallar::drivers {
namespace fs = std::filesystem;
namespace {

std::string bounded(const char* s, std::size_t n) { return {s, strnlen(s, n)}; }

bool all_digits(std::string_view s) {
  return !s.empty() && s.size() <= 4 &&
         std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// "gpiochip12" -> 12; nullopt for anything else.
std::optional<unsigned> chip_number(std::string_view name) {
  constexpr std::string_view kPrefix = "gpiochip";
  if (name.substr(0, kPrefix.size()) != kPrefix) return std::nullopt;
  const std::string_view digits = name.substr(kPrefix.size());
  if (!all_digits(digits)) return std::nullopt;
  return static_cast<unsigned>(std::stoul(std::string(digits)));
}

// The /dev/gpiochipN entries of the tree, in numeric order.
std::vector<unsigned> gpio_chips(const DeviceTree& tree) {
  std::vector<unsigned> chips;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(tree.host_path("/dev"), ec)) {
    if (const auto n = chip_number(e.path().filename().string())) chips.push_back(*n);
  }
  std::sort(chips.begin(), chips.end());
  return chips;
}

std::string chip_path(unsigned n) { return "/dev/gpiochip" + std::to_string(n); }

}  // namespace

std::optional<GpioChipInfo> read_gpio_chip_info(const fs::path& node) {
  const int fd = ::open(node.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::nullopt;
  gpiochip_info info{};
  const int rc = ::ioctl(fd, GPIO_GET_CHIPINFO_IOCTL, &info);
  const int err = errno;
  ::close(fd);
  if (rc < 0) {
    errno = err;
    return std::nullopt;
  }
  return GpioChipInfo{bounded(info.name, sizeof info.name), bounded(info.label, sizeof info.label),
                      info.lines};
}

GpioChipInfoReader gpio_chip_info_in(const fs::path& root) {
  return [root](const fs::path& node) -> std::optional<GpioChipInfo> {
    std::error_code ec;
    if (fs::is_character_file(node, ec)) return read_gpio_chip_info(node);
    const std::string name = node.filename().string();
    if (!chip_number(name)) return std::nullopt;
    const fs::path dir = root / "sys/bus/gpio/devices" / name / "gpio";
    for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
      std::ifstream label_file(e.path() / "label"), ngpio_file(e.path() / "ngpio");
      std::string label;
      unsigned lines = 0;
      if (std::getline(label_file, label) && (ngpio_file >> lines)) {
        return GpioChipInfo{name, label, lines};
      }
    }
    return std::nullopt;
  };
}

DeviceTree::DeviceTree(fs::path root, GpioChipInfoReader chip_info)
    : root_(std::move(root)), chip_info_(std::move(chip_info)) {
  if (root_.empty()) root_ = "/";
}

fs::path DeviceTree::host_path(const fs::path& device_path) const {
  if (is_system()) return device_path;
  return root_ / device_path.relative_path();
}

fs::path DeviceTree::device_path(const fs::path& host) const {
  if (is_system()) return host;
  const fs::path rel = host.lexically_relative(root_);
  if (rel.empty() || *rel.begin() == "..") return host;
  return fs::path("/") / rel;
}

std::string ResolvedNode::describe() const {
  if (node == path) return path;
  return path + " -> " + node;
}

ResolvedNode resolve_device_node(std::string_view path_text, const DeviceTree& tree) {
  const fs::path path(path_text);
  const std::string name(path_text);
  if (!path.is_absolute()) {
    throw DeviceError(printable(name, 120) + ": not an absolute device path (/dev/...)");
  }
  const fs::path host = tree.host_path(path);
  std::error_code ec;
  const fs::path real = fs::canonical(host, ec);
  if (ec) {
    std::string what = printable(name, 120) + ": no such device";
    // A udev link folder (by-path, by-id) that exists shows what is there: a camera on the
    // other port, a card under another name.
    const fs::path folder = host.parent_path();
    std::error_code dir_ec;
    if (folder.filename().string().rfind("by-", 0) == 0 && fs::is_directory(folder, dir_ec)) {
      std::vector<std::string> present;
      for (const fs::directory_entry& e : fs::directory_iterator(folder, dir_ec)) {
        present.push_back(e.path().filename().string());
      }
      std::sort(present.begin(), present.end());
      std::string list;
      for (std::size_t i = 0; i < present.size() && i < 6; ++i) {
        list += (i == 0 ? "" : ", ") + printable(present[i], 80);
      }
      if (present.size() > 6) list += ", ...";
      what += " (" + tree.device_path(folder).string() + " has " +
              (present.empty() ? std::string("nothing") : list) + ")";
    }
    throw DeviceError(what);
  }
  if (fs::is_directory(real, ec)) {
    throw DeviceError(printable(name, 120) + ": not a device node (a folder)");
  }
  return ResolvedNode{name, tree.device_path(real).string()};
}

std::string ResolvedGpioChip::describe() const {
  const std::string where =
      path + " (" + std::to_string(info.lines) + " lines, '" + info.label + "')";
  if (spec == path) return where;
  return spec + " -> " + where;
}

ResolvedGpioChip resolve_gpio_chip(std::string_view spec_text, const DeviceTree& tree) {
  const std::string spec(spec_text);
  if (spec.empty()) throw DeviceError("GPIO chip: empty name");
  auto info_of = [&](const std::string& path) {
    errno = 0;
    std::optional<GpioChipInfo> info = tree.chip_info(path);
    if (!info) {
      const int err = errno != 0 ? errno : ENODEV;
      throw DeviceError("GPIO chip '" + printable(spec) + "': " + path + ": not a GPIO chip (" +
                        std::strerror(err) + ")");
    }
    return *info;
  };
  std::string path;
  if (spec.front() == '/') {
    path = resolve_device_node(spec, tree).node;
  } else if (const auto n = chip_number(spec)) {
    path = chip_path(*n);
  } else if (all_digits(spec)) {
    path = chip_path(static_cast<unsigned>(std::stoul(spec)));
  }
  if (!path.empty()) {
    std::error_code ec;
    if (!fs::exists(tree.host_path(path), ec)) {
      throw DeviceError("GPIO chip '" + printable(spec) + "': no " + path);
    }
    return ResolvedGpioChip{spec, path, info_of(path)};
  }

  // A label: exactly one chip must carry it.
  const std::vector<unsigned> chips = gpio_chips(tree);
  if (chips.empty()) {
    throw DeviceError("GPIO chip '" + printable(spec) + "': no GPIO chips under /dev");
  }
  std::vector<ResolvedGpioChip> found;
  std::string present;
  for (const unsigned n : chips) {
    const std::string p = chip_path(n);
    errno = 0;
    const std::optional<GpioChipInfo> info = tree.chip_info(p);
    if (!present.empty()) present += ", ";
    if (!info) {
      present += "gpiochip" + std::to_string(n) +
                 " (unreadable: " + std::strerror(errno != 0 ? errno : ENODEV) + ")";
      continue;
    }
    present += "gpiochip" + std::to_string(n) + " '" + printable(info->label) + "'";
    if (info->label == spec) found.push_back(ResolvedGpioChip{spec, p, *info});
  }
  if (found.empty()) {
    throw DeviceError("GPIO chip '" + printable(spec) + "': no chip has that label (" + present +
                      ")");
  }
  if (found.size() > 1) {
    throw DeviceError("GPIO chip '" + printable(spec) + "': " + std::to_string(found.size()) +
                      " chips have that label (" + present + "): name the chip by path");
  }
  return found.front();
}

}  // namespace wallar::drivers
