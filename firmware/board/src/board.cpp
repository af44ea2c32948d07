// SPDX-License-Identifier: Apache-2.0
/// @file board.cpp
/// @brief Board file loading with a schema check.
#include "wallar/firmware/board.hpp"

#include <arpa/inet.h>

#include "wallar/core/error.hpp"
#include "wallar/drivers/config/yaml.hpp"
#include "wallar/drivers/recording/csv.hpp"

namespace wallar::firmware {
namespace fs = std::filesystem;
using config::YamlNode;

namespace {

std::string one_of(const YamlNode& node, std::initializer_list<std::string_view> allowed) {
  const std::string value = node.as_string();
  std::string list;
  for (std::string_view a : allowed) {
    if (a == value) return value;
    list += (list.empty() ? "" : ", ") + std::string(a);
  }
  node.fail("must be one of " + list + ", got '" + value + "'");
}

int positive_int(const YamlNode& node, std::int64_t max) {
  const std::int64_t v = node.as_int();
  if (v <= 0 || v > max) node.fail("must be in 1.." + std::to_string(max));
  return static_cast<int>(v);
}

double positive_double(const YamlNode& node) {
  const double v = node.as_double();
  if (!(v > 0.0)) node.fail("must be positive");
  return v;
}

fs::path resolve(const fs::path& base, const YamlNode& node) {
  const fs::path p = node.as_string();
  return p.is_absolute() ? p : (base / p).lexically_normal();
}

GpioLine parse_gpio(const YamlNode& node) {
  node.check_keys({"chip", "line", "active_low"});
  GpioLine g;
  g.chip = node.at("chip").as_string();
  const std::int64_t line = node.at("line").as_int();
  if (line < 0 || line > 1023) node.at("line").fail("must be a line offset in 0..1023");
  g.line = static_cast<int>(line);
  g.active_low = node.get_bool("active_low", false);
  return g;
}

CameraConfig parse_camera(const YamlNode& node) {
  node.check_keys({"device", "usb_id", "width", "height", "fps", "format"});
  CameraConfig c;
  c.device = node.at("device").as_string();
  if (const YamlNode* usb = node.find("usb_id")) {
    c.usb_id = usb->as_string();
    const bool ok = c.usb_id.size() == 9 && c.usb_id[4] == ':' &&
                    c.usb_id.find_first_not_of("0123456789abcdefABCDEF:") == std::string::npos;
    if (!ok) usb->fail("must be VID:PID in hex, e.g. 32e4:9750, got '" + c.usb_id + "'");
  }
  c.width_px = positive_int(node.at("width"), 16384);
  c.height_px = positive_int(node.at("height"), 16384);
  c.fps = positive_double(node.at("fps"));
  if (const YamlNode* f = node.find("format"))
    c.pixel_format = one_of(*f, {"GREY", "YUYV", "MJPG"});
  return c;
}

}  // namespace

BoardConfig parse_board(std::string_view text, const std::string& name, const fs::path& base_dir) {
  const config::YamlDocument doc = config::YamlDocument::parse(text, name);
  const YamlNode& root = doc.root();
  if (!root.is_map()) root.fail("must be a map (a board file)");
  root.check_keys({"board", "source", "replay", "cameras", "imu", "display", "tracking", "threads",
                   "calibration", "input", "live", "client"});
  BoardConfig b;
  b.file = name;

  const YamlNode& board = root.at("board");
  board.check_keys({"name", "description"});
  b.name = board.at("name").as_string();
  b.description = board.get_string("description", "");

  b.source = one_of(root.at("source"), {"replay", "live"}) == "replay"
                 ? BoardConfig::Source::kReplay
                 : BoardConfig::Source::kLive;
  if (b.source == BoardConfig::Source::kReplay) {
    const YamlNode& r = root.at("replay");
    r.check_keys({"recording", "rate", "start_offset_s", "skip", "loop"});
    b.replay.recording = resolve(base_dir, r.at("recording"));
    b.replay.rate = r.get_double("rate", 1.0);
    if (b.replay.rate < 0.0) r.at("rate").fail("must be >= 0 (0 = as fast as possible)");
    b.replay.start_offset_s = r.get_double("start_offset_s", 0.0);
    if (b.replay.start_offset_s < 0.0) r.at("start_offset_s").fail("must be >= 0");
    const std::int64_t skip = r.get_int("skip", 0);
    if (skip < 0 || skip > 1000) r.at("skip").fail("must be in 0..1000");
    b.replay.skip = static_cast<std::uint32_t>(skip);
    const std::int64_t loops = r.get_int("loop", 1);
    if (loops < 0 || loops > 1000000)
      r.at("loop").fail("must be in 0..1000000 (0 = until stopped)");
    b.replay.loops = static_cast<std::uint32_t>(loops);
  } else {
    const YamlNode& cams = root.at("cameras");
    cams.check_keys({"left", "right", "sync_tolerance_ms", "trigger"});
    b.cameras[0] = parse_camera(cams.at("left"));
    b.cameras[1] = parse_camera(cams.at("right"));
    b.sync_tolerance_ms = cams.get_double("sync_tolerance_ms", -1.0);
    if (const YamlNode* t = cams.find("trigger")) b.camera_trigger = parse_gpio(*t);
  }
  if (b.source == BoardConfig::Source::kReplay && root.has("cameras")) {
    root.at("cameras").fail(
        "is for live boards (source: live); a replay board takes its cameras "
        "from the recording");
  }

  if (const YamlNode* imu = root.find("imu")) {
    imu->check_keys({"driver", "bus", "usb_id", "address", "baud", "rate_hz", "data_ready",
                     "fifo_batch", "bus_recovery"});
    b.imu.driver = one_of(imu->at("driver"), {"none", "icm20948", "bno055"});
    if (const YamlNode* usb = imu->find("usb_id")) {
      if (b.imu.driver != "bno055") usb->fail("is for serial IMUs on a USB-UART bridge (bno055)");
      b.imu.usb_id = usb->as_string();
      const bool ok =
          b.imu.usb_id.size() == 9 && b.imu.usb_id[4] == ':' &&
          b.imu.usb_id.find_first_not_of("0123456789abcdefABCDEF:") == std::string::npos;
      if (!ok) usb->fail("must be VID:PID in hex, e.g. 10c4:ea60, got '" + b.imu.usb_id + "'");
    }
    // A serial IMU on a USB bridge may be named by its VID:PID instead of its tty.
    if (b.imu.driver != "none" && (b.imu.usb_id.empty() || imu->has("bus")))
      b.imu.bus = imu->at("bus").as_string();
    if (b.imu.driver == "icm20948") {
      const std::int64_t addr = imu->at("address").as_int();
      if (addr < 0x08 || addr > 0x77) imu->at("address").fail("must be a 7-bit address 0x08..0x77");
      b.imu.address = static_cast<std::uint8_t>(addr);
    }
    if (const YamlNode* baud = imu->find("baud")) b.imu.baud = positive_int(*baud, 4'000'000);
    if (const YamlNode* rate = imu->find("rate_hz")) b.imu.rate_hz = positive_double(*rate);
    if (const YamlNode* dr = imu->find("data_ready")) b.imu.data_ready = parse_gpio(*dr);
    if (const YamlNode* fb = imu->find("fifo_batch")) {
      if (b.imu.driver != "icm20948") fb->fail("is for FIFO IMUs on I2C (icm20948)");
      b.imu.fifo_batch = positive_int(*fb, 21);  // half the 42-record FIFO
    }
    if (const YamlNode* rec = imu->find("bus_recovery")) {
      if (b.imu.driver != "icm20948") rec->fail("is for I2C IMUs (icm20948)");
      rec->check_keys({"rebind", "scl", "sda"});
      ImuConfig::BusRecovery r;
      r.rebind = rec->get_bool("rebind", true);
      if (const YamlNode* scl = rec->find("scl")) r.scl = parse_gpio(*scl);
      if (const YamlNode* sda = rec->find("sda")) r.sda = parse_gpio(*sda);
      if (r.scl.has_value() != r.sda.has_value()) {
        rec->fail("needs both scl and sda (the bus clear drives both lines), or neither");
      }
      if (!r.rebind && !r.scl) rec->fail("asks for nothing: rebind is false and no lines given");
      b.imu.bus_recovery = r;
    }
  }

  if (const YamlNode* d = root.find("display")) {
    d->check_keys({"backend", "card", "connector", "width", "height", "lens_k1", "lens_k2"});
    b.display.backend = one_of(d->at("backend"), {"headless", "kms"});
    b.display.card = d->get_string("card", b.display.card);
    b.display.connector = d->get_string("connector", "");
    if (const YamlNode* w = d->find("width")) b.display.width_px = positive_int(*w, 16384);
    if (const YamlNode* h = d->find("height")) b.display.height_px = positive_int(*h, 16384);
    b.display.lens_k1 = d->get_double("lens_k1", 0.0);
    b.display.lens_k2 = d->get_double("lens_k2", 0.0);
  }

  if (const YamlNode* t = root.find("tracking")) {
    t->check_keys({"max_tracks", "keyframe_points", "max_map_points", "max_keyframes",
                   "pyramid_levels", "mapping_thread"});
    TrackingConfig& tc = b.tracking;
    if (const YamlNode* n = t->find("max_tracks")) tc.max_tracks = positive_int(*n, 5000);
    if (const YamlNode* n = t->find("keyframe_points"))
      tc.keyframe_points = positive_int(*n, 20000);
    if (const YamlNode* n = t->find("max_map_points"))
      tc.max_map_points = positive_int(*n, 10'000'000);
    if (const YamlNode* n = t->find("max_keyframes")) tc.max_keyframes = positive_int(*n, 100'000);
    if (const YamlNode* n = t->find("pyramid_levels")) tc.pyramid_levels = positive_int(*n, 6);
    if (const YamlNode* n = t->find("mapping_thread")) tc.mapping_thread = n->as_bool();
    if (tc.max_tracks < 8) t->at("max_tracks").fail("must be at least 8");
    if (tc.max_map_points < tc.max_tracks + tc.keyframe_points) {
      t->fail("max_map_points must hold at least max_tracks + keyframe_points");
    }
    if (tc.max_keyframes < 2) t->at("max_keyframes").fail("must be at least 2");
  }

  if (const YamlNode* th = root.find("threads")) {
    th->check_keys({kThreadNames[0], kThreadNames[1], kThreadNames[2], kThreadNames[3],
                    kThreadNames[4], kThreadNames[5], kThreadNames[6], kThreadNames[7],
                    kThreadNames[8], kThreadNames[9], kThreadNames[10], kThreadNames[11]});
    static_assert(std::size(kThreadNames) == 12, "threads: check_keys lists every name");
    for (const std::string_view thread : kThreadNames) {
      const YamlNode* n = th->find(std::string(thread));
      if (n == nullptr) continue;
      n->check_keys({"policy", "priority", "cpu"});
      ThreadPlacementConfig t;
      t.name = std::string(thread);
      if (const YamlNode* p = n->find("priority")) {
        const std::int64_t v = p->as_int();
        if (v < 0 || v > 99) p->fail("must be in 0..99 (0: SCHED_OTHER)");
        t.priority = static_cast<int>(v);
      }
      if (const YamlNode* cpu = n->find("cpu")) {
        const std::int64_t v = cpu->as_int();
        if (v < -1 || v > 1023) cpu->fail("must be a CPU number 0..1023, or -1 for any");
        t.cpu = static_cast<int>(v);
      }
      if (const YamlNode* p = n->find("policy")) {
        const std::string v = p->as_string();
        if (v == "other") {
          t.policy = ThreadPolicy::kOther;
          if (t.priority.value_or(0) != 0) {
            n->at("priority").fail("must be 0 (or absent) with policy: other");
          }
        } else if (v == "fifo" || v == "rr") {
          t.policy = v == "fifo" ? ThreadPolicy::kFifo : ThreadPolicy::kRoundRobin;
          if (t.priority.value_or(0) == 0) {
            p->fail("'" + v + "' needs a real-time priority: 'priority: 1..99' beside it");
          }
        } else {
          p->fail("must be fifo, rr or other, got '" + v + "'");
        }
      }
      b.threads.push_back(t);
    }
  }

  if (const YamlNode* c = root.find("calibration")) b.calibration = resolve(base_dir, *c);

  if (const YamlNode* in = root.find("input")) {
    in->check_keys({"reset_button", "exit_button", "keys"});
    if (const YamlNode* k = in->find("keys")) b.keys = k->as_string();
    if (const YamlNode* r = in->find("reset_button")) b.reset_button = parse_gpio(*r);
    if (const YamlNode* e = in->find("exit_button")) b.exit_button = parse_gpio(*e);
  }

  if (const YamlNode* l = root.find("live")) {
    l->check_keys({"address", "port", "token_file", "image_rate_hz", "jpeg_quality"});
    LiveConfig live;
    if (const YamlNode* a = l->find("address")) {
      live.address = a->as_string();
      in_addr addr{};
      if (inet_pton(AF_INET, live.address.c_str(), &addr) != 1) {
        a->fail("must be an IPv4 address (127.0.0.1: this machine only; 0.0.0.0: every network)");
      }
    }
    if (const YamlNode* p = l->find("port")) {
      const std::int64_t v = p->as_int();
      if (v < 0 || v > 65535) p->fail("must be in 0..65535 (0: any free port)");
      live.port = static_cast<int>(v);
    }
    if (const YamlNode* t = l->find("token_file")) live.token_file = resolve(base_dir, *t);
    if (const YamlNode* r = l->find("image_rate_hz")) {
      live.image_rate_hz = r->as_double();
      if (!(live.image_rate_hz >= 0.0 && live.image_rate_hz <= 60.0))
        r->fail("must be in 0..60 (0: no images)");
    }
    if (const YamlNode* q = l->find("jpeg_quality")) live.jpeg_quality = positive_int(*q, 100);
    b.live = live;
  }

  if (const YamlNode* c = root.find("client")) {
    c->check_keys({"socket", "group", "mode"});
    ClientConfig client;
    if (const YamlNode* s = c->find("socket")) {
      client.socket = s->as_string();
      if (client.socket.empty() || client.socket.size() > 107)
        s->fail("must be a path of 1..107 bytes (a UNIX socket's limit)");
      if (client.socket.front() != '/') client.socket = (base_dir / client.socket).string();
    }
    if (const YamlNode* g = c->find("group")) client.group = g->as_string();
    if (const YamlNode* m = c->find("mode")) {
      // YAML reads 0660 as an integer in octal only by convention: take the digits as octal.
      const std::string bits = m->as_string();
      const bool octal = !bits.empty() && bits.size() <= 4 &&
                         bits.find_first_not_of("01234567") == std::string::npos;
      if (!octal) m->fail("must be octal permission bits, as 0660");
      client.mode = static_cast<unsigned>(std::stoul(bits, nullptr, 8));
      if ((client.mode & 0600U) != 0600U)
        m->fail("must let the owner read and write (0600 at least)");
    }
    b.client = client;
  }
  return b;
}

void set_live_endpoint(LiveConfig& live, const std::string& spec, const std::string& what) {
  const std::size_t colon = spec.rfind(':');
  const std::string address = colon == std::string::npos ? live.address : spec.substr(0, colon);
  const std::string port = colon == std::string::npos ? spec : spec.substr(colon + 1);
  in_addr addr{};
  if (inet_pton(AF_INET, address.c_str(), &addr) != 1) {
    throw InputError(what + ": '" + spec + "': the address must be IPv4 (as 127.0.0.1:8765)");
  }
  const bool digits = !port.empty() && port.size() <= 5 &&
                      port.find_first_not_of("0123456789") == std::string::npos;
  if (!digits || std::stoi(port) > 65535) {
    throw InputError(what + ": '" + spec +
                     "': the port must be 0..65535 (as 8765 or 0.0.0.0:8765)");
  }
  live.address = address;
  live.port = std::stoi(port);
}

BoardConfig load_board(const fs::path& path) {
  BoardConfig b = parse_board(recording::read_text_file(path), path.string(),
                              path.parent_path().empty() ? fs::path(".") : path.parent_path());
  b.file = path;
  return b;
}

}  // namespace wallar::firmware
