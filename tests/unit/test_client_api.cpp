// SPDX-License-Identifier: Apache-2.0
/// @file test_client_api.cpp
/// @brief The client API: the shared-memory seqlock under a racing writer, the protocol's
/// parsing (garbage, oversized, version mismatch), planes with OpenXR conventions, merges
/// (subsumed-by), slow and hostile clients, and libwallar-client's prediction against the
/// firmware's ClientServer in the same process.
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <thread>

#include "wallar/client/wire.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/firmware/appliance/client_server.hpp"
#include "wallar_client.h"
#include "wallar_client.hpp"

namespace fs = std::filesystem;
namespace cw = wallar::client_wire;
using namespace wallar;
using namespace wallar::firmware;

namespace {

// A wall in the plane n.p = d with a rectangular extent (u, v in the plane, u x v = n).
Wall make_wall(std::uint32_t id, SurfaceKind kind, const Eigen::Vector3d& n, double d,
               double half_u, double half_v, std::uint32_t inliers = 100) {
  Wall w;
  w.id = id;
  w.kind = kind;
  w.plane.n = n.normalized();
  w.plane.d = d;
  w.origin = w.plane.n * d;
  w.u = w.plane.n.unitOrthogonal();
  w.v = w.plane.n.cross(w.u);
  w.extent_uv_m = {{-half_u, -half_v}, {half_u, -half_v}, {half_u, half_v}, {-half_u, half_v}};
  w.inliers = inliers;
  return w;
}

WallModel room(std::uint64_t version) {
  WallModel m;
  m.version = version;
  m.t_ns = static_cast<TimeNs>(version) * kNsPerS;
  m.gravity_aligned = true;  // found knowing down: the kinds hold
  // Floor 1.5 m below (n up, toward the viewer at the origin), a wall 2 m ahead along +x.
  m.walls.push_back(make_wall(1, SurfaceKind::kFloor, {0, 0, 1}, -1.5, 2.0, 2.0, 500));
  m.walls.push_back(make_wall(2, SurfaceKind::kWall, {-1, 0, 0}, -2.0, 1.5, 1.0, 300));
  return m;
}

// This process's folder of sockets, removed at exit.
struct SocketDir {
  fs::path dir = fs::temp_directory_path() / ("wallar_client_test_" + std::to_string(getpid()));
  SocketDir() { fs::create_directories(dir); }
  ~SocketDir() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

std::string temp_socket(const char* name) {
  static const SocketDir sockets;
  return (sockets.dir / name).string();
}

int raw_connect(const std::string& path) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strcpy(addr.sun_path, path.c_str());
  EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0) << path;
  return fd;
}

// Reads until the peer closes (or 3 s); returns what came.
std::string read_until_closed(int fd) {
  std::string got;
  char buf[4096];
  for (int i = 0; i < 300; ++i) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 10) <= 0) continue;
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) return got;
    got.append(buf, static_cast<std::size_t>(n));
  }
  return got;
}

template <typename F>
bool eventually(F f, int ms = 3000) {
  for (int i = 0; i < ms / 5; ++i) {
    if (f()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return f();
}

// Events until `stop` says so (or 3 s).
std::vector<wallar_event> events_until(wallar::Client& c,
                                       const std::function<bool(const wallar_event&)>& stop) {
  std::vector<wallar_event> all;
  for (int i = 0; i < 300; ++i) {
    for (const wallar_event& e : c.poll(10)) {
      all.push_back(e);
      if (stop(e)) return all;
    }
  }
  return all;
}

// The view the fixture's server gives apps: a camera 2 cm ahead of and turned against the body.
SE3d fixture_view() {
  SE3d T = SE3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.02, -0.035, 0.01);
  return T;
}

struct Fixture {
  Seqlock<PoseSnapshot> pose;
  TripleBuffer<WallModel> walls;
  std::unique_ptr<ClientServer> server;
  explicit Fixture(const std::string& path, ClientServerOptions o = {}) {
    ClientConfig config;
    config.socket = path;
    config.group = "";  // the owner only
    server =
        std::make_unique<ClientServer>(config, SE3d::Identity(), fixture_view(), pose, walls, o);
    server->start(ThreadSpec{"client", 0, -1, 0});
  }
  void publish(const WallModel& m) {
    walls.back() = m;
    walls.publish();
  }
};

}  // namespace

TEST(ClientWire, SeqlockInSharedMemoryNeverGivesATornPose) {
  const int fd = ::memfd_create("seqlock-test", MFD_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, cw::kShmBytes), 0);
  void* w = ::mmap(nullptr, cw::kShmBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  void* r = ::mmap(nullptr, cw::kShmBytes, PROT_READ, MAP_SHARED, fd, 0);  // as a client maps it
  ASSERT_NE(w, MAP_FAILED);
  ASSERT_NE(r, MAP_FAILED);
  cw::SharedPoseWriter writer(static_cast<cw::SharedPoseBlock*>(w));
  const auto* block = static_cast<const cw::SharedPoseBlock*>(r);
  ASSERT_TRUE(cw::shared_pose_valid(block));
  // The writer stores until the reader has read enough (a loaded machine may run one thread
  // long before the other), at least kMinStores times, at most for 10 s.
  constexpr std::uint64_t kMinStores = 100000, kMinReads = 50000;
  std::atomic<std::uint64_t> reads{0}, stores{0};
  std::atomic<bool> done{false};
  std::thread t([&] {
    cw::PosePayload p;
    // At least 400 ms of racing: on a loaded 2-core machine the two threads overlap rarely,
    // and a writer that forgot the odd sequence was caught in 1 run of 3 at 10 ms.
    const auto start = std::chrono::steady_clock::now();
    const auto give_up = start + std::chrono::seconds(10);
    std::uint64_t k = 0;
    auto more = [&] {
      const auto now = std::chrono::steady_clock::now();
      return k < kMinStores || now < start + std::chrono::milliseconds(400) ||
             (reads.load() < kMinReads && now < give_up);
    };
    while (!done.load() && more()) {  // the reader stops it early on a bad read
      ++k;
      // Every field a function of k: a torn read mixes two k's.
      p.t_pose_ns = static_cast<std::int64_t>(k);
      p.t_imu_ns = static_cast<std::int64_t>(3 * k);
      for (int i = 0; i < 3; ++i) {
        p.p_world_body_m[i] = double(k) * (i + 1);
        p.omega_body_rad_s[i] = -double(k) * (i + 1);
      }
      p.q_world_body_xyzw[3] = double(k);
      p.updates = k;
      writer.store(p);
    }
    stores.store(k);
    done.store(true);
  });
  std::uint64_t torn = 0, last = 0;
  std::string bad;  // the first inconsistent read (the writer is joined before asserting)
  cw::PosePayload p;
  while (!done.load() && bad.empty()) {
    if (!cw::try_read_shared_pose(block, p)) {
      ++torn;
      continue;
    }
    const auto k = p.updates;
    if (k == 0) continue;  // the initial value, before the first store
    reads.fetch_add(1);
    bool ok = k >= last && p.t_pose_ns == static_cast<std::int64_t>(k) &&
              p.t_imu_ns == static_cast<std::int64_t>(3 * k) && p.q_world_body_xyzw[3] == double(k);
    for (int i = 0; i < 3; ++i) {
      ok = ok && p.p_world_body_m[i] == double(k) * (i + 1) &&
           p.omega_body_rad_s[i] == -double(k) * (i + 1);
    }
    if (!ok) bad = "read " + std::to_string(k) + " after " + std::to_string(last);
    last = k;
  }
  done.store(true);
  t.join();
  ASSERT_TRUE(bad.empty()) << "a torn or stale value: " << bad;
  // A store in progress (an odd sequence, as a writer preempted mid-store leaves it): no read.
  auto* seq = &static_cast<cw::SharedPoseBlock*>(w)->seq;
  cw::Word(*seq).fetch_add(1);
  EXPECT_FALSE(cw::try_read_shared_pose(block, p));
  cw::Word(*seq).fetch_add(1);
  ASSERT_TRUE(cw::try_read_shared_pose(block, p));
  EXPECT_EQ(p.updates, stores.load());
  EXPECT_GE(reads.load(), kMinReads);
  std::printf("seqlock: %llu stores, %llu consistent reads, %llu torn attempts retried\n",
              static_cast<unsigned long long>(stores.load()),
              static_cast<unsigned long long>(reads.load()), static_cast<unsigned long long>(torn));
  ::munmap(w, cw::kShmBytes);
  ::munmap(r, cw::kShmBytes);
  ::close(fd);
}

TEST(ClientWire, HelloParsingRefusesGarbageShortAndForeignMessages) {
  const auto ok = cw::encode_hello(cw::kProtocolVersion, "app\x01name");
  const cw::Header h = cw::parse_header(ok.data());
  EXPECT_EQ(h.type, cw::MsgType::kHello);
  ASSERT_EQ(h.body_bytes + cw::kHeaderBytes, ok.size());
  const cw::Hello good = cw::parse_hello(ok.data() + cw::kHeaderBytes, h.body_bytes);
  EXPECT_TRUE(good.error.empty()) << good.error;
  EXPECT_EQ(good.version, cw::kProtocolVersion);
  EXPECT_EQ(good.name, "app?name");  // printable only
  EXPECT_NE(cw::parse_hello(ok.data() + cw::kHeaderBytes, 5).error, "");
  const auto foreign = cw::encode_hello(1, "x", 0xdeadbeef);
  EXPECT_NE(cw::parse_hello(foreign.data() + 8, foreign.size() - 8).error.find("magic"),
            std::string::npos);
  std::vector<std::uint8_t> long_name(8 + cw::kMaxNameBytes + 1, 'a');
  std::memcpy(long_name.data(), &cw::kHelloMagic, 4);
  EXPECT_NE(cw::parse_hello(long_name.data(), long_name.size()).error, "");
}

TEST(ClientWire, PlaneBatchesRoundTripAndDamagedOnesAreRefused) {
  ClientPlanes planes;
  const cw::PlaneBatch batch = planes.update(room(1), Eigen::Vector3d(0, 0, -1));
  std::vector<std::uint8_t> msg;
  cw::encode_planes(msg, batch);
  const cw::Header h = cw::parse_header(msg.data());
  ASSERT_EQ(h.body_bytes + 8, msg.size());
  const auto back = cw::parse_planes(msg.data() + 8, h.body_bytes, h.flags);
  ASSERT_TRUE(back);
  ASSERT_EQ(back->planes.size(), 2u);
  EXPECT_EQ(back->planes[1].polygon_m, batch.planes[1].polygon_m);
  // Every truncation is refused; random bytes never crash and never pass as longer than sent.
  for (std::size_t n = 0; n < h.body_bytes; ++n)
    EXPECT_FALSE(cw::parse_planes(msg.data() + 8, n, 0)) << n;
  std::mt19937_64 rng(20);
  for (int i = 0; i < 2000; ++i) {
    std::vector<std::uint8_t> junk(rng() % 400);
    for (auto& b : junk) b = static_cast<std::uint8_t>(rng());
    (void)cw::parse_planes(junk.data(), junk.size(), 0);
  }
}

TEST(ClientPlanes, OpenXrConventionsAndLabels) {
  const Eigen::Vector3d down(0, 0, -1);
  for (const Wall& w : room(1).walls) {
    const cw::PlaneRecord r = plane_record(w, down, true);
    const Eigen::Quaterniond q(r.q_world_plane_xyzw[3], r.q_world_plane_xyzw[0],
                               r.q_world_plane_xyzw[1], r.q_world_plane_xyzw[2]);
    // +z of the plane frame is the normal toward the viewer; the origin lies on the plane.
    EXPECT_LT((q * Eigen::Vector3d::UnitZ() - w.plane.n).norm(), 1e-9);
    const Eigen::Vector3d c(r.p_world_plane_m[0], r.p_world_plane_m[1], r.p_world_plane_m[2]);
    EXPECT_NEAR(w.plane.signed_distance(c), 0.0, 1e-9);
    // Counter-clockwise seen from +z, the corners in the world as the wall's.
    double area2 = 0;
    for (std::size_t i = 0; i < r.polygon_m.size(); ++i) {
      const auto& a = r.polygon_m[i];
      const auto& b = r.polygon_m[(i + 1) % r.polygon_m.size()];
      area2 += a[0] * b[1] - b[0] * a[1];
    }
    EXPECT_GT(area2, 0);
    for (std::size_t i = 0; i < w.extent_uv_m.size(); ++i) {
      double best = 1e9;
      for (const auto& xy : r.polygon_m)
        best = std::min(best, (c + q * Eigen::Vector3d(xy[0], xy[1], 0) - w.corner(i)).norm());
      EXPECT_LT(best, 1e-9);
    }
  }
  const cw::PlaneRecord floor = plane_record(room(1).walls[0], down, true);
  EXPECT_EQ(floor.semantic, cw::Semantic::kFloor);
  EXPECT_EQ(floor.orientation, cw::Orientation::kHorizontalUpward);
  EXPECT_DOUBLE_EQ(floor.extent_m[0], 4.0);
  const cw::PlaneRecord wall = plane_record(room(1).walls[1], down, true);
  EXPECT_EQ(wall.semantic, cw::Semantic::kWall);
  EXPECT_EQ(wall.orientation, cw::Orientation::kVertical);
  const Wall ceiling = make_wall(3, SurfaceKind::kCeiling, {0, 0, -1}, -1.0, 1, 1);
  EXPECT_EQ(plane_record(ceiling, down, true).orientation, cw::Orientation::kHorizontalDownward);
  EXPECT_EQ(plane_record(ceiling, std::nullopt, true).semantic, cw::Semantic::kCeiling);
  // A "wall" 30 degrees off vertical: arbitrary, label unknown.
  const Wall slanted =
      make_wall(4, SurfaceKind::kWall, {-std::cos(M_PI / 6), 0, std::sin(M_PI / 6)}, -2, 1, 1);
  EXPECT_EQ(plane_record(slanted, down, true).orientation, cw::Orientation::kArbitrary);
  EXPECT_EQ(plane_record(slanted, down, true).semantic, cw::Semantic::kUnknown);
}

// A 3-D search (no down: before the attitude filter has gravity, or without an IMU on a rig
// standing still) names every surface a wall, the floor too: such a model's planes say unknown,
// and their orientation only what gravity, once known, says of the plane itself.
TEST(ClientPlanes, AModelFoundWithoutDownGivesNoLabels) {
  WallModel m = room(1);
  m.gravity_aligned = false;
  m.walls[0].kind = SurfaceKind::kWall;  // the floor, as a 3-D search names it
  for (const Wall& w : m.walls) {
    const cw::PlaneRecord r = plane_record(w, std::nullopt, false);
    EXPECT_EQ(r.orientation, cw::Orientation::kArbitrary) << w.id;
    EXPECT_EQ(r.semantic, cw::Semantic::kUnknown) << w.id;
  }
  const Eigen::Vector3d down(0, 0, -1);
  const cw::PlaneRecord floor = plane_record(m.walls[0], down, false);
  EXPECT_EQ(floor.orientation, cw::Orientation::kHorizontalUpward);
  EXPECT_EQ(floor.semantic, cw::Semantic::kUnknown);
  ClientPlanes planes;
  const cw::PlaneBatch b = planes.update(m, std::nullopt);
  ASSERT_EQ(b.planes.size(), 2u);
  for (const auto& p : b.planes) EXPECT_EQ(p.semantic, cw::Semantic::kUnknown);
}

TEST(ClientPlanes, ChangesCountAndAMergeReportsSubsumedBy) {
  ClientPlanes planes;
  const Eigen::Vector3d down(0, 0, -1);
  WallModel m = room(1);
  // A second wall piece beside wall 2, on the same plane: x = 2, further along y.
  Wall piece = make_wall(3, SurfaceKind::kWall, {-1, 0, 0}, -2.0, 0.5, 1.0, 80);
  piece.origin += 1.8 * piece.u;
  m.walls.push_back(piece);
  cw::PlaneBatch b = planes.update(m, down);
  ASSERT_EQ(b.planes.size(), 3u);
  for (const auto& p : b.planes) EXPECT_EQ(p.change, cw::PlaneChange::kAdded);
  // The same model again: no change at all.
  m.version = 2;
  EXPECT_TRUE(planes.update(m, down).planes.empty());
  // Wall 2 grows over the piece (the reconstruction merged them; the piece's id is gone).
  WallModel merged = room(3);
  merged.walls[1].extent_uv_m = {{-1.5, -1.0}, {2.5, -1.0}, {2.5, 1.0}, {-1.5, 1.0}};
  b = planes.update(merged, down);
  ASSERT_EQ(b.planes.size(), 2u);
  EXPECT_EQ(b.planes[0].id, 2u);
  EXPECT_EQ(b.planes[0].change, cw::PlaneChange::kUpdated);
  EXPECT_EQ(b.planes[0].change_count, 1u);
  EXPECT_EQ(b.planes[1].id, 3u);
  EXPECT_EQ(b.planes[1].change, cw::PlaneChange::kRemoved);
  EXPECT_EQ(b.planes[1].subsumed_by, 2u);
  // A plane that simply goes (nothing on its plane): removed, subsumed by none.
  WallModel gone = merged;
  gone.walls.pop_back();
  b = planes.update(gone, down);
  ASSERT_EQ(b.planes.size(), 1u);
  EXPECT_EQ(b.planes[0].change, cw::PlaneChange::kRemoved);
  EXPECT_EQ(b.planes[0].subsumed_by, 0u);
  // A parallel wall 0.5 m behind is not the same plane.
  EXPECT_FALSE(subsumes(make_wall(7, SurfaceKind::kWall, {-1, 0, 0}, -2.5, 3, 3),
                        make_wall(8, SurfaceKind::kWall, {-1, 0, 0}, -2.0, 1, 1)));
  EXPECT_EQ(planes.full().planes.size(), 1u);
}

TEST(ClientServer, ServesPlanesAndEventsAndRefusesAVersionMismatchWithAMessage) {
  const std::string path = temp_socket("serve.sock");
  Fixture f(path);
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read |
                fs::perms::group_write);
  wallar::Client client(path, "test");
  f.publish(room(1));
  auto events =
      events_until(client, [&](const wallar_event&) { return client.planes().size() == 2; });
  ASSERT_EQ(client.planes().size(), 2u);
  const wallar::Planes planes = client.planes();
  EXPECT_EQ(planes.model_version(), 1u);
  EXPECT_EQ(planes[0].label, WALLAR_LABEL_FLOOR);
  EXPECT_EQ(planes[1].label, WALLAR_LABEL_WALL);
  EXPECT_EQ(planes.polygon(0).size(), 4u);
  // A merge, as events: the absorbed plane is removed with subsumed_by.
  WallModel m = room(2);
  Wall piece = make_wall(3, SurfaceKind::kWall, {-1, 0, 0}, -2.0, 0.5, 1.0, 80);
  piece.origin += 1.8 * piece.u;
  m.walls.push_back(piece);
  f.publish(m);
  events_until(client, [](const wallar_event& e) {
    return e.type == WALLAR_EVENT_PLANE_ADDED && e.plane_id == 3;
  });
  WallModel merged = room(3);
  merged.walls[1].extent_uv_m = {{-1.5, -1.0}, {2.5, -1.0}, {2.5, 1.0}, {-1.5, 1.0}};
  f.publish(merged);
  events = events_until(client,
                        [](const wallar_event& e) { return e.type == WALLAR_EVENT_PLANE_REMOVED; });
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().type, WALLAR_EVENT_PLANE_REMOVED);
  EXPECT_EQ(events.back().plane_id, 3u);
  EXPECT_EQ(events.back().subsumed_by, 2u);
  // The tracking state, as an event.
  f.pose.store(make_pose_snapshot(5, SE3d::Identity(), dsp::TrackingState::kTracking, std::nullopt,
                                  0, false));
  events = events_until(
      client, [](const wallar_event& e) { return e.type == WALLAR_EVENT_TRACKING_CHANGED; });
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().tracking, WALLAR_TRACKING_TRACKING);

  // Another protocol version: refused with the firmware's message, through the C API too.
  const int fd = raw_connect(path);
  const auto hello = cw::encode_hello(99, "old");
  ASSERT_EQ(::send(fd, hello.data(), hello.size(), 0), static_cast<ssize_t>(hello.size()));
  const std::string answer = read_until_closed(fd);
  ::close(fd);
  ASSERT_GE(answer.size(), 12u);
  EXPECT_EQ(cw::parse_header(reinterpret_cast<const std::uint8_t*>(answer.data())).type,
            cw::MsgType::kRefused);
  EXPECT_NE(answer.find("protocol version 99 is not served: this wallar speaks version 1"),
            std::string::npos)
      << answer;
  EXPECT_EQ(f.server->counters().refused, 1u);
  EXPECT_EQ(f.server->counters().accepted, 1u);
  // The first client was not disturbed.
  EXPECT_EQ(client.planes().size(), 2u);
}

TEST(ClientServer, GarbageOversizedAndSilentClientsAreClosedAndCountedOnly) {
  const std::string path = temp_socket("garbage.sock");
  ClientServerOptions o;
  o.hello_timeout_ns = 200 * kNsPerMs;
  Fixture f(path, o);
  wallar::Client good(path, "good");
  // Random bytes (a fixed seed), a header announcing 1 GiB, a second hello, silence.
  std::mt19937 rng(7);
  const int garbage = raw_connect(path);
  std::vector<std::uint8_t> junk(300);
  for (auto& b : junk) b = static_cast<std::uint8_t>(rng());
  junk[0] = 0x10;  // a body length within bounds, so it is the type that is wrong
  junk[1] = junk[2] = junk[3] = 0;
  junk[4] = 0x77;
  ASSERT_GT(::send(garbage, junk.data(), junk.size(), MSG_NOSIGNAL), 0);
  const int oversized = raw_connect(path);
  std::vector<std::uint8_t> big = cw::encode_hello(1, "");
  const std::uint32_t gib = 1u << 30;
  std::memcpy(big.data(), &gib, 4);
  ASSERT_GT(::send(oversized, big.data(), big.size(), MSG_NOSIGNAL), 0);
  const int twice = raw_connect(path);
  auto h2 = cw::encode_hello(1, "a");
  h2.insert(h2.end(), h2.begin(), h2.end());
  ASSERT_GT(::send(twice, h2.data(), h2.size(), MSG_NOSIGNAL), 0);
  const int silent = raw_connect(path);
  EXPECT_TRUE(eventually([&] { return f.server->counters().malformed == 3; }))
      << f.server->counters().malformed;
  EXPECT_TRUE(eventually([&] { return f.server->counters().timeouts == 1; }));
  for (int fd : {garbage, oversized, twice, silent}) {
    (void)read_until_closed(fd);  // closed by the server
    ::close(fd);
  }
  // The good client still gets its planes.
  f.publish(room(1));
  events_until(good, [&](const wallar_event&) { return good.planes().size() == 2; });
  EXPECT_EQ(good.planes().size(), 2u);
}

TEST(ClientServer, AFrozenClientLosesUpdatesCountedAndIsResyncedWhenItReads) {
  const std::string path = temp_socket("frozen.sock");
  ClientServerOptions o;
  o.max_queue_bytes = 16 * 1024;
  Fixture f(path, o);
  // A client that says hello and then does not read (its receive buffer small).
  const int frozen = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  const int small = 4096;
  ::setsockopt(frozen, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strcpy(addr.sun_path, path.c_str());
  ASSERT_EQ(::connect(frozen, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  const auto hello = cw::encode_hello(1, "frozen");
  ASSERT_EQ(::send(frozen, hello.data(), hello.size(), 0), static_cast<ssize_t>(hello.size()));
  wallar::Client reader(path, "reader");
  ASSERT_TRUE(eventually([&] { return f.server->counters().accepted == 2; }));
  // Many big models (a polygon of 2000 corners, 32 KB a message), each seen by the server
  // (its loop wakes every 10 ms): far more than the socket's buffer and the queue hold.
  const auto t0 = std::chrono::steady_clock::now();
  constexpr std::uint64_t kModels = 100;
  for (std::uint64_t v = 1; v <= kModels; ++v) {
    WallModel m = room(v);
    m.walls[1].extent_uv_m.clear();
    for (int k = 0; k < 2000; ++k) {
      const double a = 2 * M_PI * k / 2000;
      m.walls[1].extent_uv_m.emplace_back((1.0 + 1e-3 * double(v)) * std::cos(a), std::sin(a));
    }
    f.publish(m);
    (void)reader.poll(12);
  }
  const double publish_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_TRUE(eventually([&] { return f.server->counters().dropped > 0; }));
  // The reader that keeps up ends with the newest model.
  EXPECT_TRUE(eventually([&] {
    (void)reader.poll(0);
    return reader.planes().model_version() == kModels;
  }));
  // The frozen client reads at last: everything it has is a consistent whole set.
  const std::uint64_t resyncs_before = f.server->counters().resyncs;
  std::vector<std::uint8_t> got;
  for (int i = 0; i < 200; ++i) {
    std::uint8_t buf[65536];
    pollfd p{frozen, POLLIN, 0};
    if (::poll(&p, 1, 10) <= 0) {
      if (f.server->counters().resyncs > resyncs_before) break;
      continue;
    }
    const ssize_t n = ::recv(frozen, buf, sizeof buf, 0);
    if (n <= 0) break;
    got.insert(got.end(), buf, buf + n);
  }
  EXPECT_GT(f.server->counters().resyncs, resyncs_before);
  // Parse what came: the last plane batch is a full set of the latest model.
  std::size_t at = 0;
  std::uint64_t last_full = 0;
  while (got.size() - at >= 8) {
    const cw::Header h = cw::parse_header(got.data() + at);
    if (got.size() - at < 8 + h.body_bytes) break;
    if (h.type == cw::MsgType::kPlanes && (h.flags & cw::kPlanesFull) != 0) {
      const auto b = cw::parse_planes(got.data() + at + 8, h.body_bytes, h.flags);
      ASSERT_TRUE(b);
      last_full = b->model_version;
    }
    at += 8 + h.body_bytes;
  }
  EXPECT_EQ(last_full, kModels);
  ::close(frozen);
  std::printf("frozen client: %llu updates dropped, %llu resyncs; 100 models in %.0f ms\n",
              static_cast<unsigned long long>(f.server->counters().dropped),
              static_cast<unsigned long long>(f.server->counters().resyncs), publish_ms);
}

TEST(ClientServer, LocatePredictsFromThePoseTheGyroAndTheVelocity) {
  const std::string path = temp_socket("pose.sock");
  Fixture f(path);
  wallar::Client client(path, "pose");
  wallar_pose p = client.locate(0);
  EXPECT_EQ(p.flags, 0u);  // nothing before the first pose
  // The view apps render from: the server's T_body_view, before any pose and after them.
  const auto expect_view = [&] {
    const std::array<double, 7> v = client.view();
    const Eigen::Quaterniond q(v[3], v[0], v[1], v[2]);
    EXPECT_LT(Eigen::AngleAxisd(q.toRotationMatrix().transpose() * fixture_view().linear()).angle(),
              1e-12);
    EXPECT_LT((Eigen::Vector3d(v[4], v[5], v[6]) - fixture_view().translation()).norm(), 1e-15);
  };
  expect_view();
  SharedPosePublisher& w = f.server->publisher();
  // A body moving at v = (1, 0, 0.5) m/s and turning at 1 rad/s about its z.
  const Eigen::Vector3d v(1.0, 0.0, 0.5), omega(0, 0, 1.0);
  const TimeNs t0 = 1'000'000'000;
  auto truth = [&](TimeNs t) {
    SE3d T = SE3d::Identity();
    const double s = ns_to_s(t - t0);
    T.linear() = Eigen::AngleAxisd(omega.z() * s, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = v * s;
    return T;
  };
  w.on_pose(t0 - 50 * kNsPerMs, truth(t0 - 50 * kNsPerMs), cw::Tracking::kTracking, 0, 0);
  w.on_pose(t0, truth(t0), cw::Tracking::kTracking, 0, 0);
  for (TimeNs t = t0 + 5 * kNsPerMs; t <= t0 + 20 * kNsPerMs; t += 5 * kNsPerMs) w.on_imu(t, omega);
  for (const TimeNs ahead : {0 * kNsPerMs, 16 * kNsPerMs, 33 * kNsPerMs}) {
    p = client.locate(t0 + ahead);
    EXPECT_EQ(p.flags, 15u);
    const SE3d T = truth(t0 + ahead);
    const Eigen::Quaterniond q(p.q_world_body_xyzw[3], p.q_world_body_xyzw[0],
                               p.q_world_body_xyzw[1], p.q_world_body_xyzw[2]);
    EXPECT_LT(Eigen::AngleAxisd(q.toRotationMatrix().transpose() * T.linear()).angle(), 1e-9)
        << ahead;
    EXPECT_LT((Eigen::Vector3d(p.p_world_body_m[0], p.p_world_body_m[1], p.p_world_body_m[2]) -
               T.translation())
                  .norm(),
              1e-9)
        << ahead;
  }
  // Lost: still valid (held), no longer tracked.
  w.on_pose(t0 + 30 * kNsPerMs, truth(t0), cw::Tracking::kLost, 0, 0);
  p = client.locate(t0 + 40 * kNsPerMs);
  EXPECT_EQ(p.flags, unsigned(WALLAR_POSE_ORIENTATION_VALID | WALLAR_POSE_POSITION_VALID));
  EXPECT_EQ(p.tracking, WALLAR_TRACKING_LOST);
  // Readers on other threads while the writer stores at IMU rate: every read consistent.
  std::atomic<bool> stop{false};
  std::thread reader([&] {
    while (!stop.load()) {
      const wallar_pose r = client.locate(t0);
      const double n = std::sqrt(r.q_world_body_xyzw[0] * r.q_world_body_xyzw[0] +
                                 r.q_world_body_xyzw[1] * r.q_world_body_xyzw[1] +
                                 r.q_world_body_xyzw[2] * r.q_world_body_xyzw[2] +
                                 r.q_world_body_xyzw[3] * r.q_world_body_xyzw[3]);
      ASSERT_NEAR(n, 1.0, 1e-9);
    }
  });
  for (int k = 0; k < 20000; ++k) w.on_imu(t0 + 40 * kNsPerMs + k * kNsPerMs, omega);
  stop.store(true);
  reader.join();
  expect_view();
}

TEST(ClientServer, ASecondServerOnTheSameSocketIsRefusedAndAStaleOneReplaced) {
  const std::string path = temp_socket("twice.sock");
  {
    Fixture f(path);
    ClientConfig config;
    config.socket = path;
    Seqlock<PoseSnapshot> pose;
    TripleBuffer<WallModel> walls;
    try {
      ClientServer second(config, SE3d::Identity(), SE3d::Identity(), pose, walls);
      FAIL() << "a second server on a live socket";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("another server listens on it"), std::string::npos)
          << e.what();
    }
  }
  // A stale socket file (nobody listens): replaced.
  const int stale = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strcpy(addr.sun_path, path.c_str());
  ASSERT_EQ(::bind(stale, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ::close(stale);
  Fixture again(path);
  wallar::Client c(path);
  // (The wait first, the count after: as two arguments of one EXPECT_EQ their order of
  // evaluation is unspecified, and the aarch64 build read the count before waiting.)
  EXPECT_TRUE(eventually([&] { return again.server->counters().accepted == 1; }))
      << again.server->counters().accepted;
  // A regular file at the path is not replaced.
  const std::string file = temp_socket("a_file");
  {
    std::FILE* fp = std::fopen(file.c_str(), "w");
    std::fclose(fp);
  }
  ClientConfig config;
  config.socket = file;
  Seqlock<PoseSnapshot> pose;
  TripleBuffer<WallModel> walls;
  EXPECT_THROW(ClientServer(config, SE3d::Identity(), SE3d::Identity(), pose, walls), InputError);
  fs::remove(file);
}

// The prediction on real motion: EuRoC V1_01's ground truth (20 Hz, the body = the IMU) as the
// tracked poses and its 200 Hz gyro (bias-corrected with the ground truth's bias) as the IMU,
// through the shared page and wallar_client_locate, against the ground truth at t_pose + h
// (interpolated). h = 0, 16, 33 ms and the next pose (50 ms). Beside it: holding the last
// pose (no prediction). docs/results.md ("Client API: pose prediction") has the figures.
TEST(ClientServer, PredictionOnTheEurocV101FlightBeatsHoldingThePose) {
  const auto rec = recording::read_euroc_imu(fs::path(WALLAR_TEST_DATA) / "euroc_v1_01_imu");
  ASSERT_GT(rec.ground_truth.size(), 2000u);
  const std::string path = temp_socket("flight.sock");
  Fixture f(path);
  wallar::Client client(path, "flight");
  SharedPosePublisher& w = f.server->publisher();
  const Eigen::Matrix3d R_body_imu = rec.imu_calib.T_body_imu.linear();
  constexpr TimeNs kHorizons[] = {0, 16 * kNsPerMs, 33 * kNsPerMs, 50 * kNsPerMs};
  std::vector<double> rot_deg[4], pos_mm[4], hold_rot_deg[4], hold_pos_mm[4];
  std::size_t imu = 0;
  const auto& gt = rec.ground_truth;
  auto rot_err = [](const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
    return Eigen::AngleAxisd(a.transpose() * b).angle() * 180.0 / M_PI;
  };
  for (std::size_t k = 0; k + 2 < gt.size(); ++k) {
    const TimeNs t_k = gt[k].t_ns;
    w.on_pose(t_k, gt[k].T_world_body, cw::Tracking::kTracking, 0, 0);
    while (imu < rec.imu.size() && rec.imu[imu].t_ns <= t_k) ++imu;  // before the pose
    for (int h = 0; h < 4; ++h) {
      const TimeNs t = t_k + kHorizons[h];
      // The IMU samples up to the display time have arrived (the newest one, at most 5 ms old).
      while (imu < rec.imu.size() && rec.imu[imu].t_ns <= t) {
        const ImuSample& s = rec.imu[imu++];
        const auto g = recording::ground_truth_at(gt, s.t_ns, 60 * kNsPerMs);
        const Eigen::Vector3d bias = g ? g->gyro_bias_rad_s : Eigen::Vector3d::Zero();
        w.on_imu(s.t_ns, R_body_imu * (s.gyro_rad_s - bias));
      }
      // Between two rows 50 ms apart (the ground truth's rate): interpolated.
      const auto truth = recording::ground_truth_at(gt, t, 60 * kNsPerMs);
      ASSERT_TRUE(truth) << k << " of " << gt.size();
      const wallar_pose p = client.locate(t);
      if (k == 0) continue;  // no velocity yet
      ASSERT_EQ(p.flags, 15u);
      const Eigen::Quaterniond q(p.q_world_body_xyzw[3], p.q_world_body_xyzw[0],
                                 p.q_world_body_xyzw[1], p.q_world_body_xyzw[2]);
      const Eigen::Vector3d pos(p.p_world_body_m[0], p.p_world_body_m[1], p.p_world_body_m[2]);
      rot_deg[h].push_back(rot_err(q.toRotationMatrix(), truth->T_world_body.linear()));
      pos_mm[h].push_back(1e3 * (pos - truth->T_world_body.translation()).norm());
      hold_rot_deg[h].push_back(rot_err(gt[k].T_world_body.linear(), truth->T_world_body.linear()));
      hold_pos_mm[h].push_back(
          1e3 * (gt[k].T_world_body.translation() - truth->T_world_body.translation()).norm());
    }
  }
  auto pct = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(q * double(v.size() - 1))];
  };
  for (int h = 0; h < 4; ++h) {
    std::printf(
        "ahead %2lld ms: rotation median %.3f p95 %.3f deg (held %.3f / %.3f), position median "
        "%.2f p95 %.2f mm (held %.2f / %.2f)\n",
        static_cast<long long>(kHorizons[h] / kNsPerMs), pct(rot_deg[h], 0.5),
        pct(rot_deg[h], 0.95), pct(hold_rot_deg[h], 0.5), pct(hold_rot_deg[h], 0.95),
        pct(pos_mm[h], 0.5), pct(pos_mm[h], 0.95), pct(hold_pos_mm[h], 0.5),
        pct(hold_pos_mm[h], 0.95));
  }
  // At the pose itself: the pose.
  EXPECT_LT(pct(rot_deg[0], 0.95), 1e-6);
  EXPECT_LT(pct(pos_mm[0], 0.95), 1e-6);
  for (int h = 1; h < 4; ++h) {
    // The gyro's rotation since the pose: far better than holding it.
    EXPECT_LT(pct(rot_deg[h], 0.5), 0.5 * pct(hold_rot_deg[h], 0.5)) << h;
    EXPECT_LT(pct(rot_deg[h], 0.95), 0.5 * pct(hold_rot_deg[h], 0.95)) << h;
    // The velocity: better than holding the position.
    EXPECT_LT(pct(pos_mm[h], 0.5), pct(hold_pos_mm[h], 0.5)) << h;
  }
  // Absolute bounds for this easy flight (EuRoC V1_01; measured 2026-12, docs/results.md).
  EXPECT_LT(pct(rot_deg[2], 0.95), 0.2);  // measured 0.073 deg
  EXPECT_LT(pct(pos_mm[2], 0.95), 5.0);   // measured 1.95 mm
}

TEST(ClientBoard, TheClientSectionIsReadAndBadValuesNameTheirKey) {
  const std::string head = "board: {name: t}\nsource: replay\nreplay: {recording: /r}\n";
  const BoardConfig none = parse_board(head, "b.yaml", "/base");
  EXPECT_FALSE(none.client);
  const BoardConfig b = parse_board(
      head + "client: {socket: run/c.sock, group: apps, mode: '0600'}\n", "b.yaml", "/base");
  ASSERT_TRUE(b.client);
  EXPECT_EQ(b.client->socket, "/base/run/c.sock");  // relative to the board file's folder
  EXPECT_EQ(b.client->group, "apps");
  EXPECT_EQ(b.client->mode, 0600u);
  EXPECT_EQ(parse_board(head + "client: {mode: 0640}\n", "b.yaml", "/base").client->mode, 0640u);
  const BoardConfig d = parse_board(head + "client: {}\n", "b.yaml", "/base");
  EXPECT_EQ(d.client->socket, "/run/wallar/client.sock");
  EXPECT_EQ(d.client->mode, 0660u);
  auto error_of = [&](const std::string& section) {
    try {
      (void)parse_board(head + section, "b.yaml", "/base");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("client: {mode: rw}\n").find("b.yaml:4: 'client.mode' must be octal"),
            std::string::npos)
      << error_of("client: {mode: rw}\n");
  EXPECT_NE(error_of("client: {mode: '0440'}\n").find("client.mode"), std::string::npos);
  EXPECT_NE(error_of("client: {socket: /" + std::string(120, 'x') + "}\n").find("client.socket"),
            std::string::npos);
  EXPECT_NE(error_of("client: {port: 3}\n").find("port"), std::string::npos);
}
