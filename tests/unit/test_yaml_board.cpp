// SPDX-License-Identifier: Apache-2.0
/// @file test_yaml_board.cpp
/// @brief The YAML tree's typed getters and the board files' schema check.
#include <gtest/gtest.h>

#include "test_support.hpp"
#include "wallar/drivers/config/yaml.hpp"
#include "wallar/firmware/appliance/thread_table.hpp"
#include "wallar/firmware/board.hpp"
#include "wallar/firmware/live_stereo.hpp"
#include "wallar/firmware/tracking_and_mapping.hpp"

namespace wallar::test {
namespace {

using config::YamlDocument;
using firmware::parse_board;
using ::testing::HasSubstr;

TEST(Yaml, ReadsOpenCvAndKalibrMatrices) {
  const auto doc = YamlDocument::parse(
      "%YAML:1.0\n"
      "cv: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: d\n  data: [1, 2, 3, 4]\n"
      "kalibr:\n  - [1, 2]\n  - [3, 4]\n"
      "flat: [1, 2, 3, 4]\n"
      "addr: 0x68\n",
      "m.yaml");
  for (const char* key : {"cv", "kalibr", "flat"}) {
    const Eigen::MatrixXd m = doc.root().at(key).as_matrix(2, 2);
    EXPECT_EQ(m(0, 1), 2.0) << key;
    EXPECT_EQ(m(1, 0), 3.0) << key;
  }
  EXPECT_EQ(doc.root().at("addr").as_int(), 0x68);
}

TEST(Yaml, ErrorsNameFileLineAndKeyPath) {
  const auto doc = YamlDocument::parse("a:\n  b:\n    c: twelve\n", "x.yaml");
  EXPECT_THAT(input_error_of([&] { (void)doc.root().at("a").at("b").at("c").as_int(); }),
              HasSubstr("x.yaml:3: 'a.b.c' must be an integer, got 'twelve'"));
  EXPECT_THAT(input_error_of([&] { (void)doc.root().at("a").at("z"); }),
              HasSubstr("x.yaml:2: missing key 'a.z'"));
}

TEST(Yaml, RefusesAliasesDuplicatesAndDeepNesting) {
  EXPECT_THAT(input_error_of([] { (void)YamlDocument::parse("a: &x 1\nb: *x\n", "y.yaml"); }),
              HasSubstr("y.yaml:2: YAML aliases are not supported"));
  EXPECT_THAT(input_error_of([] { (void)YamlDocument::parse("a: 1\na: 2\n", "y.yaml"); }),
              HasSubstr("y.yaml:2: duplicate key 'a'"));
  EXPECT_THAT(input_error_of([] {
                (void)YamlDocument::parse(std::string(100, '[') + std::string(100, ']'), "d.yaml");
              }),
              HasSubstr("d.yaml:1: YAML nested too deeply"));
  EXPECT_THAT(input_error_of([] { (void)YamlDocument::parse("", "e.yaml"); }),
              HasSubstr("e.yaml: empty YAML document"));
}

TEST(Board, TheShippedBoardFilesLoad) {
  const auto sim = firmware::load_board(fs::path(WALLAR_SOURCE_DIR) / "board" / "sim.yaml");
  EXPECT_EQ(sim.name, "sim");
  EXPECT_EQ(sim.source, firmware::BoardConfig::Source::kReplay);
  EXPECT_TRUE(fs::is_directory(sim.replay.recording / "mav0")) << sim.replay.recording;
  EXPECT_EQ(sim.display.backend, "headless");
  EXPECT_EQ(sim.tracking.max_tracks, 300);
  EXPECT_EQ(sim.tracking.max_map_points, 20000);
  EXPECT_TRUE(sim.tracking.mapping_thread);

  // The boot image's board: the recording on the image's data partition, played until stopped.
  const auto qemu = firmware::load_board(fs::path(WALLAR_SOURCE_DIR) / "board" / "qemu-virt.yaml");
  EXPECT_EQ(qemu.replay.recording, fs::path("/var/lib/wallar/recordings/euroc_v1_01_still"));
  EXPECT_EQ(qemu.replay.loops, 0U);

  const auto pi = firmware::load_board(fs::path(WALLAR_SOURCE_DIR) / "board" / "rpi5.yaml");
  EXPECT_EQ(pi.source, firmware::BoardConfig::Source::kLive);
  EXPECT_EQ(pi.imu.driver, "icm20948");
  EXPECT_EQ(pi.imu.bus, "/dev/i2c-1");
  EXPECT_EQ(pi.imu.address, 0x68);
  ASSERT_TRUE(pi.imu.data_ready);
  EXPECT_EQ(pi.imu.data_ready->chip, "pinctrl-rp1");  // by label: gpiochip0 or 4 by kernel
  EXPECT_EQ(pi.imu.data_ready->line, 24);
  EXPECT_EQ(pi.imu.fifo_batch, 4);
  ASSERT_TRUE(pi.imu.bus_recovery);
  EXPECT_EQ(pi.imu.bus_recovery->scl->line, 3);  // RP1 GPIO3 is I2C1's SCL, GPIO2 its SDA
  EXPECT_EQ(pi.imu.bus_recovery->sda->line, 2);
  EXPECT_EQ(pi.cameras[1].usb_id, "32e4:9750");
  EXPECT_EQ(pi.cameras[0].pixel_format, "YUYV");
  EXPECT_EQ(pi.display.connector, "HDMI-A-1");
  EXPECT_DOUBLE_EQ(pi.display.lens_k1, 0.22);  // the headset's lens pre-distortion
  EXPECT_DOUBLE_EQ(pi.display.lens_k2, 0.24);
  EXPECT_EQ(sim.display.lens_k1, 0.0);
  ASSERT_TRUE(pi.exit_button);
  EXPECT_TRUE(pi.exit_button->active_low);

  EXPECT_TRUE(pi.keys.empty());

  // The hardware-in-the-loop board: vivid cameras, a BNO055 on the UART, KMS, a uinput remote.
  const auto hil = firmware::load_board(fs::path(WALLAR_SOURCE_DIR) / "board" / "qemu-hil.yaml");
  EXPECT_EQ(hil.source, firmware::BoardConfig::Source::kLive);
  EXPECT_EQ(hil.cameras[0].device, "/dev/video0");
  EXPECT_EQ(hil.cameras[1].pixel_format, "GREY");
  EXPECT_EQ(hil.cameras[1].width_px, 752);
  EXPECT_EQ(hil.imu.driver, "bno055");
  EXPECT_EQ(hil.imu.bus, "/dev/ttyAMA0");
  EXPECT_EQ(hil.display.backend, "kms");
  EXPECT_EQ(hil.display.connector, "Virtual-1");
  EXPECT_EQ(hil.keys, "name:wallar-hil-remote");
  ASSERT_TRUE(hil.calibration);
  EXPECT_EQ(*hil.calibration, fs::path("/var/lib/wallar/recordings/euroc_v1_01_still"));

  // What the camera driver gets from it.
  const auto cams = firmware::camera_configs(pi);
  EXPECT_EQ(cams[0].name, "left");
  EXPECT_EQ(cams[1].name, "right");
  EXPECT_EQ(cams[0].device, pi.cameras[0].device);
  EXPECT_EQ(cams[1].usb_id, "32e4:9750");
  EXPECT_EQ(cams[0].format, drivers::CameraPixelFormat::kYuyv);
  EXPECT_EQ(cams[0].width_px, 640);
  EXPECT_DOUBLE_EQ(cams[1].fps, 30.0);
}

constexpr const char* kLiveBoard = R"(board:
  name: test
source: live
cameras:
  left: {device: /dev/video0, width: 640, height: 480, fps: 30}
  right: {device: /dev/video2, width: 640, height: 480, fps: 30}
imu:
  driver: icm20948
  bus: /dev/i2c-1
  address: 0x69
)";

std::string board_error(std::string text) {
  return input_error_of([&] { (void)parse_board(text, "b.yaml", "."); });
}

TEST(Board, UnknownKeyIsNamedWithItsLine) {
  std::string text = kLiveBoard;
  text.replace(text.find("address"), 7, "adress");
  EXPECT_THAT(board_error(text), HasSubstr("b.yaml:10: unknown key 'imu.adress' (allowed: "));
}

TEST(Board, MissingKeyIsNamed) {
  std::string text = kLiveBoard;
  text.replace(text.find("  bus: /dev/i2c-1\n"), 18, "");
  EXPECT_THAT(board_error(text), HasSubstr("b.yaml:8: missing key 'imu.bus'"));
}

TEST(Board, SerialImuByUsbIdOrByTty) {
  std::string text = kLiveBoard;
  const std::string icm = "  driver: icm20948\n  bus: /dev/i2c-1\n  address: 0x69\n";
  text.replace(text.find(icm), icm.size(), "  driver: bno055\n  usb_id: \"10c4:EA60\"\n");
  const auto by_usb = parse_board(text, "b.yaml", ".");
  EXPECT_EQ(by_usb.imu.driver, "bno055");
  EXPECT_EQ(by_usb.imu.usb_id, "10c4:EA60");
  EXPECT_TRUE(by_usb.imu.bus.empty());  // found through USB discovery at start-up

  std::string bad = text;
  bad.replace(bad.find("10c4:EA60"), 9, "10c4-ea60");
  EXPECT_THAT(board_error(bad), HasSubstr("b.yaml:9: 'imu.usb_id' must be VID:PID in hex"));

  std::string on_i2c = kLiveBoard;
  on_i2c.replace(on_i2c.find("  address"), 0, "  usb_id: \"10c4:ea60\"\n");
  EXPECT_THAT(board_error(on_i2c), HasSubstr("'imu.usb_id' is for serial IMUs"));

  std::string neither = text;
  neither.replace(neither.find("  usb_id"), 22, "");
  EXPECT_THAT(board_error(neither), HasSubstr("missing key 'imu.bus'"));
}

TEST(Board, WrongTypesAndRangesAreNamed) {
  std::string text = kLiveBoard;
  text.replace(text.find("0x69"), 4, "0x80");
  EXPECT_THAT(board_error(text), HasSubstr("b.yaml:10: 'imu.address' must be a 7-bit address"));
  text = kLiveBoard;
  text.replace(text.find("fps: 30}"), 8, "fps: fast}");
  EXPECT_THAT(board_error(text), HasSubstr("b.yaml:5: 'cameras.left.fps' must be a finite number"));
  text = kLiveBoard;
  text.replace(text.find("source: live"), 12, "source: cloud");
  EXPECT_THAT(board_error(text), HasSubstr("b.yaml:3: 'source' must be one of replay, live"));
}

TEST(Board, ImuFifoBatchAndBusRecoveryAreReadAndChecked) {
  const std::string icm = "  address: 0x69\n";
  std::string text = kLiveBoard;
  text.replace(text.find(icm), icm.size(),
               icm +
                   "  fifo_batch: 4\n  bus_recovery:\n    scl: {chip: pinctrl-rp1, line: 3}\n"
                   "    sda: {chip: pinctrl-rp1, line: 2}\n");
  const auto b = parse_board(text, "b.yaml", ".");
  EXPECT_EQ(b.imu.fifo_batch, 4);
  ASSERT_TRUE(b.imu.bus_recovery);
  EXPECT_TRUE(b.imu.bus_recovery->rebind);
  EXPECT_EQ(b.imu.bus_recovery->scl->line, 3);
  EXPECT_EQ(b.imu.bus_recovery->sda->chip, "pinctrl-rp1");
  EXPECT_EQ(parse_board(kLiveBoard, "b.yaml", ".").imu.fifo_batch, 1);  // the default

  std::string big = text;
  big.replace(big.find("fifo_batch: 4"), 13, "fifo_batch: 40");
  EXPECT_THAT(board_error(big), HasSubstr("'imu.fifo_batch' must be in 1..21"));
  std::string one_line = text;
  one_line.replace(one_line.find("    sda:"),
                   std::string("    sda: {chip: pinctrl-rp1, line: 2}\n").size(), "");
  EXPECT_THAT(board_error(one_line),
              HasSubstr("'imu.bus_recovery' needs both scl and sda (the bus clear drives both "
                        "lines), or neither"));
  std::string nothing = kLiveBoard;
  nothing.replace(nothing.find(icm), icm.size(), icm + "  bus_recovery: {rebind: false}\n");
  EXPECT_THAT(board_error(nothing), HasSubstr("'imu.bus_recovery' asks for nothing"));
}

TEST(Board, TrackingCapacitiesAreReadAndChecked) {
  std::string text =
      std::string(kLiveBoard) +
      "tracking:\n  max_tracks: 150\n  max_map_points: 5000\n  mapping_thread: false\n";
  const auto b = parse_board(text, "b.yaml", ".");
  EXPECT_EQ(b.tracking.max_tracks, 150);
  EXPECT_EQ(b.tracking.max_map_points, 5000);
  EXPECT_EQ(b.tracking.keyframe_points, 800);  // the default
  EXPECT_FALSE(b.tracking.mapping_thread);
  const firmware::TrackingOptions o = firmware::tracking_options(b.tracking);
  EXPECT_EQ(o.tracker.max_tracks, 150);
  EXPECT_FALSE(o.mapping_thread);

  std::string small = text;
  small.replace(small.find("max_map_points: 5000"), 20, "max_map_points: 500 ");
  EXPECT_THAT(board_error(small),
              HasSubstr("b.yaml:12: 'tracking' max_map_points must hold at least max_tracks"));
  std::string typo = text;
  typo.replace(typo.find("max_tracks"), 10, "max_track ");
  EXPECT_THAT(board_error(typo), HasSubstr("b.yaml:12: unknown key 'tracking.max_track'"));
}

// threads: the board places the thread table's threads (priority, CPU); a name the table does
// not have, or a value out of range, is named with its line. Every table name is a board key.
TEST(Board, ThreadPlacementsAreReadCheckedAndApplied) {
  const std::string text = std::string(kLiveBoard) +
                           "threads:\n  tracking: {cpu: 2}\n  capture: {priority: 72, cpu: -1}\n";
  const auto b = parse_board(text, "b.yaml", ".");
  ASSERT_EQ(b.threads.size(), 2u);
  const firmware::ThreadSpec tracking = firmware::thread_spec("tracking", true, &b);
  EXPECT_EQ(tracking.cpu, 2);
  EXPECT_EQ(tracking.priority, 60);  // the table's
  const firmware::ThreadSpec capture = firmware::thread_spec("capture", true, &b);
  EXPECT_EQ(capture.priority, 72);
  EXPECT_EQ(capture.cpu, -1);
  EXPECT_EQ(firmware::thread_spec("capture", false, &b).priority, 0);  // not in real time
  EXPECT_EQ(firmware::thread_spec("mapping", true, &b).cpu, -1);       // untouched
  // The Pi board keeps tracking and bundle adjustment off CPU 0 (the USB interrupts).
  const auto pi = firmware::load_board(fs::path(WALLAR_SOURCE_DIR) / "board" / "rpi5.yaml");
  EXPECT_EQ(firmware::thread_spec("tracking", true, &pi).cpu, 2);
  EXPECT_EQ(firmware::thread_spec("mapping", true, &pi).cpu, 3);

  std::string unknown = text;
  unknown.replace(unknown.find("tracking: {"), 8, "trackin ");
  EXPECT_THAT(board_error(unknown), HasSubstr("unknown key 'threads.trackin'"));
  std::string priority = text;
  priority.replace(priority.find("priority: 72"), 12, "priority: 99");
  EXPECT_NO_THROW(parse_board(priority, "b.yaml", "."));
  priority.replace(priority.find("priority: 99"), 12, "priority: 100");
  EXPECT_THAT(board_error(priority), HasSubstr("must be in 0..99"));
  std::string cpu = text;
  cpu.replace(cpu.find("cpu: 2"), 6, "cpu: x");
  EXPECT_THAT(board_error(cpu), HasSubstr("threads.tracking.cpu"));
  // The policy: rr keeps the priority and asks for SCHED_RR, other drops a table priority.
  const auto policies = parse_board(std::string(kLiveBoard) +
                                        "threads:\n  capture: {policy: rr, priority: 65}\n"
                                        "  imu: {policy: other}\n  tracking: {policy: fifo, "
                                        "priority: 61}\n",
                                    "b.yaml", ".");
  const firmware::ThreadSpec rr = firmware::thread_spec("capture", true, &policies);
  EXPECT_TRUE(rr.round_robin);
  EXPECT_EQ(rr.priority, 65);
  EXPECT_EQ(firmware::thread_spec("imu", true, &policies).priority, 0);  // table: 80
  EXPECT_FALSE(firmware::thread_spec("tracking", true, &policies).round_robin);
  EXPECT_EQ(firmware::thread_spec("tracking", true, &policies).priority, 61);
  EXPECT_FALSE(firmware::thread_spec("capture", true, &b).round_robin);
  EXPECT_THAT(board_error(std::string(kLiveBoard) + "threads:\n  imu: {policy: rr}\n"),
              HasSubstr("'threads.imu.policy' 'rr' needs a real-time priority"));
  EXPECT_THAT(
      board_error(std::string(kLiveBoard) + "threads:\n  imu: {policy: other, priority: 5}\n"),
      HasSubstr("'threads.imu.priority' must be 0 (or absent) with policy: other"));
  EXPECT_THAT(board_error(std::string(kLiveBoard) + "threads:\n  imu: {policy: batch}\n"),
              HasSubstr("must be fifo, rr or other, got 'batch'"));
  // The board's names are the thread table's, both ways.
  std::vector<std::string> table,
      board_names(std::begin(firmware::kThreadNames), std::end(firmware::kThreadNames));
  for (const firmware::ThreadTableEntry& e : firmware::thread_table()) table.emplace_back(e.name);
  std::sort(table.begin(), table.end());
  std::sort(board_names.begin(), board_names.end());
  EXPECT_EQ(table, board_names);
}

TEST(Board, RelativeRecordingPathsResolveAgainstTheBoardFile) {
  const auto b = parse_board("board: {name: s}\nsource: replay\nreplay: {recording: ../rec}\n",
                             "dir/b.yaml", "/opt/wallar/board");
  EXPECT_EQ(b.replay.recording, fs::path("/opt/wallar/rec"));
  EXPECT_THAT(board_error("board: {name: s}\nsource: replay\nreplay: {recording: r, rate: -1}\n"),
              HasSubstr("b.yaml:3: 'replay.rate' must be >= 0"));
}

TEST(Board, ReplayLoopsAreReadAndChecked) {
  const auto once =
      parse_board("board: {name: s}\nsource: replay\nreplay: {recording: r}\n", "b.yaml", "/b");
  EXPECT_EQ(once.replay.loops, 1U);  // the default: play it once
  const auto forever = parse_board(
      "board: {name: s}\nsource: replay\nreplay: {recording: r, loop: 0}\n", "b.yaml", "/b");
  EXPECT_EQ(forever.replay.loops, 0U);  // until stopped
  EXPECT_THAT(board_error("board: {name: s}\nsource: replay\nreplay: {recording: r, loop: -2}\n"),
              HasSubstr("b.yaml:3: 'replay.loop' must be in 0..1000000 (0 = until stopped)"));
}

TEST(Board, TheLiveServerIsOffUnlessAskedAndItsKeysAreChecked) {
  const std::string base = "board: {name: s}\nsource: replay\nreplay: {recording: r}\n";
  EXPECT_FALSE(parse_board(base, "b.yaml", "/b").live);  // off by default
  const auto on = parse_board(base + "live: {}\n", "b.yaml", "/b");
  ASSERT_TRUE(on.live);
  EXPECT_EQ(on.live->address, "127.0.0.1");  // this machine only, unless an address is given
  EXPECT_EQ(on.live->port, 8765);
  EXPECT_FALSE(on.live->token_file);
  const auto all = parse_board(base +
                                   "live: {address: 0.0.0.0, port: 9000, token_file: tok, "
                                   "image_rate_hz: 2.5, jpeg_quality: 50}\n",
                               "b.yaml", "/etc/wallar");
  EXPECT_EQ(all.live->address, "0.0.0.0");
  EXPECT_EQ(all.live->port, 9000);
  EXPECT_EQ(*all.live->token_file, fs::path("/etc/wallar/tok"));
  EXPECT_DOUBLE_EQ(all.live->image_rate_hz, 2.5);
  EXPECT_EQ(all.live->jpeg_quality, 50);
  EXPECT_THAT(board_error(base + "live: {port: 70000}\n"),
              HasSubstr("b.yaml:4: 'live.port' must be in 0..65535"));
  EXPECT_THAT(board_error(base + "live: {address: headset.local}\n"),
              HasSubstr("b.yaml:4: 'live.address' must be an IPv4 address"));
  EXPECT_THAT(board_error(base + "live: {image_rate_hz: 100}\n"),
              HasSubstr("'live.image_rate_hz' must be in 0..60"));
  EXPECT_THAT(board_error(base + "live: {prot: 1}\n"), HasSubstr("unknown key 'live.prot'"));

  // `wallar run --live [ADDRESS:]PORT`.
  firmware::LiveConfig live;
  firmware::set_live_endpoint(live, "9001", "--live");
  EXPECT_EQ(live.address, "127.0.0.1");
  EXPECT_EQ(live.port, 9001);
  firmware::set_live_endpoint(live, "0.0.0.0:0", "--live");
  EXPECT_EQ(live.address, "0.0.0.0");
  EXPECT_EQ(live.port, 0);
  EXPECT_THAT(input_error_of([&] { firmware::set_live_endpoint(live, "host:80", "--live"); }),
              HasSubstr("--live: 'host:80': the address must be IPv4"));
  EXPECT_THAT(input_error_of([&] { firmware::set_live_endpoint(live, "1.2.3.4:99999", "--live"); }),
              HasSubstr("the port must be 0..65535"));
  EXPECT_THAT(input_error_of([&] { firmware::set_live_endpoint(live, "", "--live"); }),
              HasSubstr("the port must be"));
}

}  // namespace
}  // namespace wallar::test
