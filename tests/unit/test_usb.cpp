// SPDX-License-Identifier: Apache-2.0
/// @file test_usb.cpp
/// @brief USB ids, port paths, sysfs node lookup on a fake tree, and enumeration on a machine
/// that may have no USB at all (this container): an empty list or a clear error, no crash.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "test_support.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/usb/usb.hpp"

namespace wallar::drivers {
namespace {

using ::testing::HasSubstr;

TEST(Usb, ParsesVidPid) {
  EXPECT_EQ(parse_usb_id("32e4:9750"), (UsbId{0x32E4, 0x9750}));
  EXPECT_EQ(parse_usb_id("32E4:9750"), (UsbId{0x32E4, 0x9750}));
  EXPECT_EQ(parse_usb_id("0000:ffff"), (UsbId{0x0000, 0xFFFF}));
  EXPECT_EQ(format_usb_id(UsbId{0x32E4, 0x0750}), "32e4:0750");
  EXPECT_EQ(parse_usb_id(format_usb_id(UsbId{0xABCD, 0x0001})), (UsbId{0xABCD, 0x0001}));
}

TEST(Usb, BadIdsAreOneLineErrorsNamingThem) {
  for (const char* bad : {"", "32e4", "32e4:975", "32e4-9750", "xyz1:9750", "32e4:9750:1",
                          " 32e4:9750", "32e4:97500", "0x32e4:9750"}) {
    try {
      parse_usb_id(bad, "board.yaml: cameras.left.usb_id");
      FAIL() << "accepted '" << bad << "'";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_THAT(msg, HasSubstr("board.yaml: cameras.left.usb_id: bad USB id '"));
      EXPECT_THAT(msg, HasSubstr(std::string("'") + bad + "'"));
      EXPECT_EQ(msg.find('\n'), std::string::npos);
    }
  }
}

TEST(Usb, PortPathIsTheSysfsName) {
  EXPECT_EQ(usb_port_path(1, {1, 2}), "1-1.2");
  EXPECT_EQ(usb_port_path(3, {4}), "3-4");
  EXPECT_EQ(usb_port_path(2, {}), "usb2");
  UsbDeviceInfo info;
  info.bus = 4;
  info.ports = {1, 3, 2};
  EXPECT_EQ(info.port_path(), "4-1.3.2");
}

TEST(Usb, FindsTtyAndVideoNodesInSysfs) {
  test::TempDir tmp;
  const auto& root = tmp.path();
  namespace fs = std::filesystem;
  fs::create_directories(root / "1-1.2/1-1.2:1.0/ttyUSB3");             // usb-serial (FTDI, CP210x)
  fs::create_directories(root / "1-1.3/1-1.3:1.0/tty/ttyACM0");         // cdc-acm
  fs::create_directories(root / "1-1.4/1-1.4:1.0/video4linux/video2");  // uvcvideo
  fs::create_directories(root / "1-1.4/1-1.4:1.0/video4linux/video3");
  fs::create_directories(root / "1-1.4/1-1.4:1.1");  // streaming interface
  fs::create_directories(root / "1-1.4/power");      // not an interface
  fs::create_directories(root / "1-1.4/power/video9");

  EXPECT_EQ(find_device_nodes("1-1.2", root).tty, std::vector<std::string>{"/dev/ttyUSB3"});
  EXPECT_TRUE(find_device_nodes("1-1.2", root).video.empty());
  EXPECT_EQ(find_device_nodes("1-1.3", root).tty, std::vector<std::string>{"/dev/ttyACM0"});
  const UsbDeviceNodes cam = find_device_nodes("1-1.4", root);
  EXPECT_EQ(cam.video, (std::vector<std::string>{"/dev/video2", "/dev/video3"}));
  EXPECT_TRUE(cam.tty.empty());
  const UsbDeviceNodes none = find_device_nodes("9-9", root);
  EXPECT_TRUE(none.tty.empty() && none.video.empty());
  EXPECT_TRUE(find_device_nodes("1-1", "/nonexistent/sysfs").tty.empty());
}

// In a container there may be no /dev/bus/usb: libusb either starts and finds nothing that
// matches, or refuses with one clear line. Both are fine; a crash is not.
TEST(Usb, EnumerationWithoutUsbIsEmptyOrAClearError) {
  try {
    UsbContext ctx;
    const UsbId id = parse_usb_id("32e4:9750");
    for (const UsbDeviceInfo& d : ctx.enumerate(id)) {
      EXPECT_EQ(d.id, id);  // the filter holds for whatever is there
      EXPECT_FALSE(d.port_path().empty());
    }
    const std::vector<UsbDeviceInfo> all = ctx.enumerate();
    for (std::size_t i = 1; i < all.size(); ++i) {
      EXPECT_LE(all[i - 1].bus, all[i].bus);  // bus order
    }
    if (ctx.has_hotplug()) {
      auto reg = ctx.register_hotplug(id, [](const UsbDeviceInfo&, bool) {});
      EXPECT_NE(reg, nullptr);
      ctx.handle_events(1 * kNsPerMs);
    }
    EXPECT_THROW(ctx.reset_device(255, {7, 7, 7}), UsbError);  // no such device
  } catch (const UsbError& e) {
    const std::string msg = e.what();
    EXPECT_THAT(msg, HasSubstr("libusb: "));
    EXPECT_THAT(msg, HasSubstr("LIBUSB_ERROR_"));
    EXPECT_EQ(msg.find('\n'), std::string::npos);
  }
}

}  // namespace
}  // namespace wallar::drivers
