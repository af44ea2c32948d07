// SPDX-License-Identifier: Apache-2.0
/// @file test_device_names.cpp
/// @brief Devices by stable name against fake /dev trees: GPIO chips by label whatever their
/// number, udev links followed; the Pi 5 board checked (`wallar run --check`'s check_board)
/// against a Pi 5 tree of each kernel generation, a wrong camera mode named by its key.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "fake_v4l2.hpp"
#include "test_support.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/devices/device_names.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/board_devices.hpp"

namespace wallar::test {
namespace {
namespace fs = std::filesystem;
using drivers::DeviceTree;
using drivers::GpioChipInfo;

// A folder holding dev/ (and etc/): regular files stand for device nodes, udev's links are
// relative symbolic links as udev makes them; GPIO chips answer from a table, as the kernel's
// GPIO_GET_CHIPINFO_IOCTL would.
class FakeTree {
 public:
  explicit FakeTree(const std::string& name)
      : root_(fs::temp_directory_path() / ("wallar_devtree_" + name)) {
    fs::remove_all(root_);
    fs::create_directories(root_ / "dev");
  }
  ~FakeTree() { fs::remove_all(root_); }
  FakeTree(const FakeTree&) = delete;
  FakeTree& operator=(const FakeTree&) = delete;

  void node(const std::string& path) {
    const fs::path p = root_ / fs::path(path).relative_path();
    fs::create_directories(p.parent_path());
    std::ofstream(p) << "";
  }
  void link(const std::string& path, const std::string& target) {
    const fs::path p = root_ / fs::path(path).relative_path();
    fs::create_directories(p.parent_path());
    fs::create_symlink(target, p);
  }
  void chip(unsigned n, const std::string& label, unsigned lines) {
    const std::string path = "/dev/gpiochip" + std::to_string(n);
    node(path);
    chips_[(root_ / path.substr(1)).string()] = {"gpiochip" + std::to_string(n), label, lines};
  }
  void file(const std::string& path, const std::string& text) {
    const fs::path p = root_ / fs::path(path).relative_path();
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
  }
  [[nodiscard]] DeviceTree tree() const {
    return DeviceTree(root_, [chips = chips_](const fs::path& p) -> std::optional<GpioChipInfo> {
      const auto it = chips.find(p.string());
      if (it == chips.end()) {
        errno = ENOTTY;
        return std::nullopt;
      }
      return it->second;
    });
  }

 private:
  fs::path root_;
  std::map<std::string, GpioChipInfo> chips_;
};

// The Pi 5's chips on a kernel since 6.6.45 (the RP1 header chip first) or before (fourth).
void pi5_gpio(FakeTree& t, bool current_kernel) {
  if (current_kernel) {
    t.chip(0, "pinctrl-rp1", 54);
    t.chip(10, "gpio-brcmstb@107d508500", 32);
    t.chip(11, "gpio-brcmstb@107d508520", 4);
    t.chip(12, "gpio-brcmstb@107d517c00", 17);
    t.chip(13, "gpio-brcmstb@107d517c20", 6);
  } else {
    t.chip(0, "gpio-brcmstb@107d508500", 32);
    t.chip(1, "gpio-brcmstb@107d508520", 4);
    t.chip(2, "gpio-brcmstb@107d517c00", 17);
    t.chip(3, "gpio-brcmstb@107d517c20", 6);
    t.chip(4, "pinctrl-rp1", 54);
  }
}

// Two UVC cameras (probe order swapped against the ports), the I2C bus, vc4 and v3d, and the
// rig calibration where board/rpi5.yaml names it.
void pi5_devices(FakeTree& t, int calibrated_width) {
  t.node("/dev/video0");
  t.node("/dev/video2");
  t.link("/dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0", "../../video2");
  t.link("/dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0", "../../video0");
  t.node("/dev/i2c-1");
  // RP1's I2C1 in sysfs: the adapter under its controller, the controller's driver.
  t.node("/sys/devices/platform/axi/1000120000.pcie/1f00074000.i2c/i2c-1/name");
  t.link("/sys/bus/i2c/devices/i2c-1",
         "../../../devices/platform/axi/1000120000.pcie/1f00074000.i2c/i2c-1");
  t.node("/sys/bus/platform/drivers/i2c_designware/bind");
  t.node("/sys/bus/platform/drivers/i2c_designware/unbind");
  t.link("/sys/devices/platform/axi/1000120000.pcie/1f00074000.i2c/driver",
         "../../../../../bus/platform/drivers/i2c_designware");
  t.node("/dev/dri/card0");
  t.node("/dev/dri/card1");
  t.link("/dev/dri/by-path/platform-1002000000.v3d-card", "../card0");
  t.link("/dev/dri/by-path/platform-axi:gpu-card", "../card1");
  const std::string w = std::to_string(calibrated_width);
  t.file("/etc/wallar/calibration/rig.yaml", R"(cam0:
  T_cam_imu:
  - [0.0, -1.0, 0.0, 0.02]
  - [1.0, 0.0, 0.0, 0.0]
  - [0.0, 0.0, 1.0, 0.0]
  - [0.0, 0.0, 0.0, 1.0]
  distortion_coeffs: [0, 0, 0, 0]
  intrinsics: [400, 400, 320, 240]
  resolution: [)" + w + R"(, 480]
cam1:
  T_cn_cnm1:
  - [1.0, 0.0, 0.0, -0.06]
  - [0.0, 1.0, 0.0, 0.0]
  - [0.0, 0.0, 1.0, 0.0]
  - [0.0, 0.0, 0.0, 1.0]
  distortion_coeffs: [0, 0, 0, 0]
  intrinsics: [400, 400, 320, 240]
  resolution: [)" + w + R"(, 480]
)");
}

firmware::BoardConfig pi5_board() {
  return firmware::load_board(fs::path(WALLAR_SOURCE_DIR) / "board" / "rpi5.yaml");
}

std::string found(const firmware::BoardCheck& c, const std::string& key) {
  for (const auto& f : c.found) {
    if (f.key == key) return f.found;
  }
  return "(not found: " + key + ")";
}

std::string problems(const firmware::BoardCheck& c) {
  std::string s;
  for (const auto& p : c.problems) s += p.line + "\n";
  return s;
}

TEST(DeviceNames, AGpioChipIsFoundByLabelNameNumberOrPathWhateverItsNumber) {
  for (const bool current : {true, false}) {
    FakeTree t(current ? "gpio_new" : "gpio_old");
    pi5_gpio(t, current);
    const DeviceTree tree = t.tree();
    const std::string rp1 = current ? "/dev/gpiochip0" : "/dev/gpiochip4";
    const drivers::ResolvedGpioChip chip = drivers::resolve_gpio_chip("pinctrl-rp1", tree);
    EXPECT_EQ(chip.path, rp1);
    EXPECT_EQ(chip.info.lines, 54u);
    EXPECT_EQ(chip.describe(), "pinctrl-rp1 -> " + rp1 + " (54 lines, 'pinctrl-rp1')");
    // Name, number and path name the chip of that number, whatever its label.
    EXPECT_EQ(drivers::resolve_gpio_chip("gpiochip0", tree).info.label,
              current ? "pinctrl-rp1" : "gpio-brcmstb@107d508500");
    EXPECT_EQ(drivers::resolve_gpio_chip(current ? "0" : "4", tree).path, rp1);
    EXPECT_EQ(drivers::resolve_gpio_chip(rp1, tree).info.label, "pinctrl-rp1");
  }
}

TEST(DeviceNames, AnUnknownOrAmbiguousGpioChipNamesWhatIsThere) {
  FakeTree t("gpio_bad");
  t.chip(0, "pinctrl-bcm2711", 58);
  t.chip(1, "raspberrypi-exp-gpio", 8);
  const DeviceTree tree = t.tree();
  try {
    drivers::resolve_gpio_chip("pinctrl-rp1", tree);
    FAIL() << "no throw";
  } catch (const DeviceError& e) {
    EXPECT_EQ(std::string(e.what()),
              "GPIO chip 'pinctrl-rp1': no chip has that label (gpiochip0 'pinctrl-bcm2711', "
              "gpiochip1 'raspberrypi-exp-gpio')");
  }
  EXPECT_THROW(drivers::resolve_gpio_chip("gpiochip4", tree), DeviceError);
  t.chip(2, "raspberrypi-exp-gpio", 8);
  try {
    drivers::resolve_gpio_chip("raspberrypi-exp-gpio", t.tree());
    FAIL() << "no throw";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("2 chips have that label"), std::string::npos);
  }
  // A node that does not answer the GPIO ioctl is not taken for a chip.
  t.node("/dev/gpiochip3");
  EXPECT_THROW(drivers::resolve_gpio_chip("3", t.tree()), DeviceError);
  FakeTree empty("gpio_none");
  EXPECT_THROW(drivers::resolve_gpio_chip("pinctrl-rp1", empty.tree()), DeviceError);
}

TEST(DeviceNames, UdevLinksAreFollowedToTheirNodesAndAMissingOneShowsItsFolder) {
  FakeTree t("links");
  pi5_devices(t, 640);
  const DeviceTree tree = t.tree();
  const drivers::ResolvedNode left = drivers::resolve_device_node(
      "/dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0", tree);
  EXPECT_EQ(left.node, "/dev/video2");
  EXPECT_EQ(drivers::resolve_device_node("/dev/dri/by-path/platform-axi:gpu-card", tree).node,
            "/dev/dri/card1");
  EXPECT_EQ(drivers::resolve_device_node("/dev/i2c-1", tree).describe(), "/dev/i2c-1");
  try {
    drivers::resolve_device_node("/dev/dri/by-path/platform-gpu-card", tree);
    FAIL() << "no throw";
  } catch (const DeviceError& e) {
    EXPECT_EQ(std::string(e.what()),
              "/dev/dri/by-path/platform-gpu-card: no such device (/dev/dri/by-path has "
              "platform-1002000000.v3d-card, platform-axi:gpu-card)");
  }
  EXPECT_THROW(drivers::resolve_device_node("/dev/dri", tree), DeviceError);   // a folder
  EXPECT_THROW(drivers::resolve_device_node("dev/i2c-1", tree), DeviceError);  // not absolute
}

// `wallar run --check --board board/rpi5.yaml` on a Pi 5 of either kernel generation: every
// device the board names is found, the GPIO chips replaced by the RP1 chip's path, and the
// camera modes are the calibration's.
TEST(BoardDevices, ThePi5BoardResolvesEveryDeviceOnAPi5TreeOfEitherKernel) {
  const firmware::BoardConfig board = pi5_board();
  for (const bool current : {true, false}) {
    FakeTree t(current ? "pi5_new" : "pi5_old");
    pi5_gpio(t, current);
    pi5_devices(t, 640);
    const DeviceTree tree = t.tree();
    const firmware::BoardCheck check = firmware::check_board(board, tree);
    EXPECT_TRUE(check.ok()) << problems(check);
    const std::string rp1 = current ? "/dev/gpiochip0" : "/dev/gpiochip4";
    EXPECT_EQ(found(check, "cameras.left.device"),
              "/dev/v4l/by-path/platform-xhci-hcd.1-usb-0:1:1.0-video-index0 -> /dev/video2");
    EXPECT_EQ(found(check, "cameras.right.device"),
              "/dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0 -> /dev/video0");
    EXPECT_EQ(found(check, "imu.data_ready.chip"),
              "pinctrl-rp1 -> " + rp1 + " (54 lines, 'pinctrl-rp1'), line 24");
    for (const char* key :
         {"cameras.trigger.chip", "input.reset_button.chip", "input.exit_button.chip"}) {
      EXPECT_NE(found(check, key).find(rp1), std::string::npos) << key;
    }
    EXPECT_EQ(found(check, "imu.bus"), "/dev/i2c-1");
    EXPECT_EQ(found(check, "display.card"),
              "/dev/dri/by-path/platform-axi:gpu-card -> /dev/dri/card1");
    EXPECT_EQ(found(check, "calibration"), "/etc/wallar/calibration/rig.yaml");
    EXPECT_EQ(found(check, "cameras.left mode"), "640x480 YUYV @ 30 Hz, as calibrated");
    EXPECT_EQ(found(check, "imu.bus_recovery"), "rebinds 1f00074000.i2c (i2c_designware)");
    EXPECT_EQ(found(check, "imu.bus_recovery.scl.chip"),
              "pinctrl-rp1 -> " + rp1 + " (54 lines, 'pinctrl-rp1'), line 3");
    EXPECT_EQ(check.found.size(), 14u);
    // What `run --check` measures with: the board as the product opens it (chips by path).
    ASSERT_TRUE(check.resolved.imu.data_ready.has_value());
    EXPECT_EQ(check.resolved.imu.data_ready->chip, rp1);
    // What the appliance opens: the chips by path.
    firmware::BoardCheck again;
    const firmware::BoardConfig resolved = firmware::resolve_board_devices(board, tree, &again);
    EXPECT_EQ(resolved.imu.data_ready->chip, rp1);
    EXPECT_EQ(resolved.reset_button->chip, rp1);
    EXPECT_EQ(resolved.camera_trigger->chip, rp1);
    EXPECT_EQ(resolved.cameras[0].device, board.cameras[0].device);  // links stay links
  }
}

// `wallar run --check` asks each camera it finds what it offers (VIDIOC_ENUM_FMT, _FRAMESIZES,
// _FRAMEINTERVALS): the board's mode must be one of them, one line per camera that cannot.
TEST(BoardDevices, EachCameraIsAskedWhetherItOffersTheBoardsMode) {
  const firmware::BoardConfig board = pi5_board();  // 640x480 YUYV at 30 Hz
  FakeTree t("pi5_modes");
  pi5_gpio(t, true);
  pi5_devices(t, 640);
  FakeCameraSpec vga;
  vga.width_px = 640;
  vga.height_px = 480;
  {
    FakeV4l2 v4l2;
    v4l2.add_device("/dev/video2", vga);  // left (by-path -> video2)
    v4l2.add_device("/dev/video0", vga);
    const firmware::BoardCheck check = firmware::check_board(board, t.tree(), &v4l2);
    EXPECT_TRUE(check.ok()) << problems(check);
    EXPECT_EQ(found(check, "cameras.left mode on /dev/video2"), "YUYV 640x480 @ 30 Hz offered");
    EXPECT_EQ(found(check, "cameras.right mode on /dev/video0"), "YUYV 640x480 @ 30 Hz offered");
  }
  FakeCameraSpec hd = vga;
  hd.width_px = 1280;
  hd.height_px = 720;
  hd.fourccs = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
  FakeCameraSpec slow = vga;
  slow.fps = 25.0;
  FakeV4l2 v4l2;
  v4l2.add_device("/dev/video2", slow);
  v4l2.add_device("/dev/video0", hd);
  const firmware::BoardCheck check = firmware::check_board(board, t.tree(), &v4l2);
  ASSERT_EQ(check.problems.size(), 2u) << problems(check);
  EXPECT_EQ(check.problems[0].line,
            "cameras.left.fps: 30 Hz is not offered by /dev/video2 at YUYV 640x480 (it offers "
            "GREY 640x480 @ 25/12.5 Hz, YUYV 640x480 @ 25/12.5 Hz, MJPG 640x480 @ 25/12.5 Hz)");
  EXPECT_EQ(check.problems[1].line,
            "cameras.right.format/width/height: YUYV 640x480 is not a mode of /dev/video0 (it "
            "offers YUYV 1280x720 @ 30/15 Hz, MJPG 1280x720 @ 30/15 Hz)");
  EXPECT_TRUE(check.any_bad_input());  // the board asks what the device cannot: exit 2
}

TEST(BoardDevices, AWrongCameraModeIsBadInputThatNamesTheKey) {
  const firmware::BoardConfig board = pi5_board();
  FakeTree t("pi5_mode");
  pi5_gpio(t, true);
  pi5_devices(t, 752);  // calibrated at 752x480, the board captures 640x480
  const firmware::BoardCheck check = firmware::check_board(board, t.tree());
  ASSERT_EQ(check.problems.size(), 2u) << problems(check);
  EXPECT_TRUE(check.any_bad_input());
  EXPECT_EQ(check.problems[0].line,
            "cameras.left.width/height: 640x480 but /etc/wallar/calibration/rig.yaml "
            "calibrates cam0 at 752x480 (calibrate at the mode the board captures, or capture "
            "at the calibrated one)");
  EXPECT_EQ(check.problems[1].line.substr(0, 26), "cameras.right.width/height");
  try {
    firmware::throw_if_failed(board, check);
    FAIL() << "no throw";
  } catch (const InputError& e) {  // exit 2
    EXPECT_NE(std::string(e.what()).find("rpi5.yaml: cameras.left.width/height: 640x480"),
              std::string::npos);
    EXPECT_NE(std::string(e.what()).find("(1 more problem above)"), std::string::npos);
  }
  // A rate the calibration gives must be the board's too.
  RigCalibration rig;
  for (CameraCalibration& c : rig.cams) {
    c.width_px = 640;
    c.height_px = 480;
    c.rate_hz = 20.0;
  }
  rig.imu_extrinsic_known = true;
  firmware::BoardCheck rate;
  firmware::check_rig(board, rig, "rig.yaml", &rate);
  ASSERT_EQ(rate.problems.size(), 2u);
  EXPECT_EQ(rate.problems[0].line, "cameras.left.fps: 30 Hz but rig.yaml gives cam0 20 Hz");
}

// `wallar record` and `wallar imu` check the devices they open, by the same resolver, before
// opening them; neither needs a calibration (a recording made to calibrate has none yet).
TEST(BoardDevices, SensorCommandsCheckTheirOwnDevicesAndNeedNoCalibration) {
  FakeTree t("pi5_sensors");
  pi5_gpio(t, true);
  pi5_devices(t, 640);
  firmware::BoardConfig board = pi5_board();
  board.calibration.reset();
  const firmware::BoardConfig resolved =
      firmware::check_sensor_board(board, t.tree(), {"cameras", "imu"});
  EXPECT_EQ(resolved.imu.data_ready->chip, "/dev/gpiochip0");
  EXPECT_EQ(resolved.imu.bus_recovery->scl->chip, "/dev/gpiochip0");
  // The cameras gone: the IMU command does not care, the recorder names each.
  fs::remove(fs::path(t.tree().root()) /
             "dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0");
  EXPECT_NO_THROW(firmware::check_sensor_board(board, t.tree(), {"imu"}));
  std::vector<std::string> lines;
  try {
    firmware::check_sensor_board(board, t.tree(), {"cameras", "imu"},
                                 [&](const std::string& l) { lines.push_back(l); });
    FAIL() << "no throw";
  } catch (const DeviceError& e) {  // exit 1: a device is missing
    EXPECT_NE(std::string(e.what()).find("cameras.right.device"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(lines.empty());  // the only problem
  // A calibration the board names is checked against the camera modes (exit 2).
  FakeTree m("pi5_sensors_mode");
  pi5_gpio(m, true);
  pi5_devices(m, 752);
  EXPECT_THROW(firmware::check_sensor_board(pi5_board(), m.tree(), {"cameras", "imu"}), InputError);
  EXPECT_NO_THROW(firmware::check_sensor_board(pi5_board(), m.tree(), {"imu"}));
}

TEST(BoardDevices, MissingDevicesAreEachOneLineWithTheirKeyAndTheBoardNoMore) {
  firmware::BoardConfig board = pi5_board();
  FakeTree t("pi5_missing");
  pi5_gpio(t, true);
  pi5_devices(t, 640);
  fs::remove(fs::path(t.tree().root()) /
             "dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0");
  fs::remove(fs::path(t.tree().root()) / "dev/i2c-1");
  board.imu.data_ready->line = 60;  // beyond the RP1 chip's 54 lines: the board file's fault
  const firmware::BoardCheck check = firmware::check_board(board, t.tree());
  ASSERT_EQ(check.problems.size(), 3u) << problems(check);
  EXPECT_EQ(check.problems[0].line,
            "cameras.right.device: /dev/v4l/by-path/platform-xhci-hcd.0-usb-0:1:1.0-video-index0: "
            "no such device (/dev/v4l/by-path has platform-xhci-hcd.1-usb-0:1:1.0-video-index0)");
  EXPECT_EQ(check.problems[1].line, "imu.bus: /dev/i2c-1: no such device");
  EXPECT_EQ(check.problems[2].line,
            "imu.data_ready.line: 60 is not on pinctrl-rp1 -> /dev/gpiochip0 (54 lines, "
            "'pinctrl-rp1') (lines 0..53)");
  EXPECT_TRUE(check.problems[2].bad_input);
  EXPECT_FALSE(check.problems[0].bad_input);
  // Both cameras on one node: a board file's mistake.
  board = pi5_board();
  board.cameras[1].device = "/dev/video2";
  const firmware::BoardCheck same = firmware::check_board(board, t.tree());
  ASSERT_EQ(same.problems.size(), 2u) << problems(same);  // and the I2C bus, still missing
  EXPECT_EQ(same.problems[0].line,
            "cameras.right.device: /dev/video2 is the left camera's node too (/dev/video2)");
  EXPECT_TRUE(same.problems[0].bad_input);
}

}  // namespace
}  // namespace wallar::test
