// SPDX-License-Identifier: Apache-2.0
/// @file board.hpp
/// @brief One YAML file per board: where the sensors are and how the appliance runs on it.
///
/// The loader checks the schema: an unknown key, a missing required key or a value of the
/// wrong type is an InputError that names the file, the line and the key path. Relative paths
/// in the file are resolved against the board file's folder.
///
/// Threading: a loaded BoardConfig is immutable; share it read-only.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace wallar::firmware {

/// A GPIO line through the character device (libgpiod): chip name or path, and offset.
struct GpioLine {
  std::string chip;  //!< "gpiochip0" or "/dev/gpiochip4"
  int line = -1;     //!< offset within the chip
  bool active_low = false;
};

struct CameraConfig {
  std::string device;  //!< "/dev/video0"
  std::string usb_id;  //!< "VID:PID" for hot-plug discovery and USB reset, may be empty
  int width_px = 640;
  int height_px = 480;
  double fps = 30.0;
  std::string pixel_format = "GREY";  //!< GREY, YUYV or MJPG
};

struct ImuConfig {
  std::string driver = "none";  //!< none, icm20948 (I2C) or bno055 (UART)
  std::string bus;              //!< "/dev/i2c-1" or a serial device
  std::string usb_id;           //!< serial IMUs: "VID:PID" of the USB-UART bridge, whose tty
                                //!< is found at start-up when `bus` is empty
  std::uint8_t address = 0;     //!< 7-bit I2C address (I2C drivers)
  int baud = 115200;            //!< serial drivers
  double rate_hz = 200.0;
  std::optional<GpioLine> data_ready;
  /// I2C IMUs: records per FIFO read (batches share one transaction's overhead; each record
  /// keeps its own time stamp, back-dated by the period).
  int fifo_batch = 1;
  /// I2C IMUs: how a stuck bus is freed (drivers/bus/i2c_recovery.hpp); absent: not at all.
  struct BusRecovery {
    bool rebind = true;  //!< unbind and bind the adapter's platform driver around the clocks
    std::optional<GpioLine> scl;  //!< the bus's pins as GPIO lines, for the bus clear
    std::optional<GpioLine> sda;
  };
  std::optional<BusRecovery> bus_recovery;
};

struct DisplayConfig {
  std::string backend = "headless";  //!< headless (EGL pbuffer) or kms (DRM/KMS + GBM)
  std::string card = "/dev/dri/card0";
  std::string connector;  //!< "HDMI-A-1", empty = first connected
  int width_px = 1280;
  int height_px = 720;
  /// Lens pre-distortion of the headset's optics, r (1 + k1 r^2 + k2 r^4); 0, 0 = none.
  double lens_k1 = 0.0;
  double lens_k2 = 0.0;
};

/// The tracker's fixed-capacity storage, allocated once at start-up from these.
struct TrackingConfig {
  int max_tracks = 300;       //!< features tracked per frame
  int keyframe_points = 800;  //!< new map points per key-frame
  int max_map_points = 20000;
  int max_keyframes = 128;  //!< key-frame records kept for relocalisation
  int pyramid_levels = 3;
  bool mapping_thread = true;  //!< false: map in lock step on the tracking thread
};

/// threads.NAME: a thread of the appliance's thread table placed by the board (the thread table,
/// firmware/appliance/thread_table.hpp, has the defaults and the names).
/// threads.NAME.policy: the scheduling policy in real time.
enum class ThreadPolicy { kOther, kFifo, kRoundRobin };

struct ThreadPlacementConfig {
  std::string name;             //!< "tracking", "capture", ...
  std::optional<int> priority;  //!< SCHED_FIFO 1..99 in real time; 0: SCHED_OTHER
  std::optional<int> cpu;       //!< the CPU it is pinned to; -1: any
  /// other (priority 0), fifo or rr (with a priority 1..99); absent: fifo for a priority above
  /// 0, other for 0.
  std::optional<ThreadPolicy> policy;
};

/// The names threads.NAME may take (the thread table's).
inline constexpr const char* kThreadNames[] = {"imu",        "capture", "replay",      "push",
                                               "tracking",   "mapping", "reconstruct", "render",
                                               "supervisor", "log",     "live",        "client"};

/// live: the live server (Foxglove's WebSocket protocol, firmware/appliance/live_publisher.hpp).
/// Off unless the board has the section or `wallar run --live` asks.
struct LiveConfig {
  std::string address = "127.0.0.1";  //!< IPv4 address to listen on (0.0.0.0: every one)
  int port = 8765;                    //!< 0: any free port (said in the log)
  /// A file whose first line is the token clients must give (ws://HOST:PORT/?token=...).
  std::optional<std::filesystem::path> token_file;
  double image_rate_hz = 5.0;  //!< JPEG images per second per camera (0: none)
  int jpeg_quality = 70;       //!< 1..100
};

/// client: the client API server (firmware/appliance/client_server.hpp), a UNIX stream socket
/// for libwallar-client. Off unless the board has the section or `wallar run --client-socket`
/// asks.
struct ClientConfig {
  std::string socket = "/run/wallar/client.sock";  //!< its path (at most 107 bytes)
  std::string group = "wallar";  //!< the socket's group, when it exists (else the process's)
  unsigned mode = 0660;          //!< the socket's permission bits
};

struct ReplayConfig {
  std::filesystem::path recording;  //!< EuRoC recording (absolute after loading)
  double rate = 1.0;                //!< 0 = as fast as possible
  double start_offset_s = 0.0;
  std::uint32_t skip = 0;
  std::uint32_t loops = 1;  //!< times the recording is played; 0 = until stopped (a soak, a demo)
};

struct BoardConfig {
  std::filesystem::path file;
  std::string name;
  std::string description;
  enum class Source : std::uint8_t { kReplay, kLive } source = Source::kReplay;
  ReplayConfig replay;              //!< source == kReplay
  CameraConfig cameras[2];          //!< source == kLive: left, right
  double sync_tolerance_ms = -1.0;  //!< < 0: half the frame period
  std::optional<GpioLine> camera_trigger;
  ImuConfig imu;
  DisplayConfig display;
  TrackingConfig tracking;
  std::vector<ThreadPlacementConfig> threads;        //!< threads: overrides of the thread table
  std::optional<std::filesystem::path> calibration;  //!< EuRoC-style folder or Kalibr YAML
  std::optional<GpioLine> reset_button;
  std::optional<GpioLine> exit_button;
  /// input.keys: an evdev keyboard or headset remote (R resets, Q/Esc exits), as
  /// `wallar run --keys` takes it (/dev/input/..., or name:TEXT); empty: none. --keys wins.
  std::string keys;
  std::optional<LiveConfig> live;  //!< live: (the live server); `wallar run --live` sets it
  /// client: (the client API socket); `wallar run --client-socket` sets it
  std::optional<ClientConfig> client;
};

/// "[ADDRESS:]PORT" (`wallar run --live`) into `live`'s address and port; throws InputError
/// naming `what` on anything else.
void set_live_endpoint(LiveConfig& live, const std::string& spec, const std::string& what);

/// Reads and checks a board file; throws InputError "FILE:LINE: ..." naming the bad key.
BoardConfig load_board(const std::filesystem::path& path);
/// The same from text (tests, fuzzing); relative paths resolve against `base_dir`.
BoardConfig parse_board(std::string_view text, const std::string& name,
                        const std::filesystem::path& base_dir);

}  // namespace wallar::firmware
