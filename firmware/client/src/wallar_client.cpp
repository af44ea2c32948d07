// SPDX-License-Identifier: Apache-2.0
/// @file wallar_client.cpp
/// @brief libwallar-client: the C API over the protocol of wallar/client/wire.hpp.
#include "wallar_client.h"

#include <poll.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <map>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include "wallar/client/wire.hpp"

namespace cw = wallar::client_wire;

struct wallar_planes {
  std::uint64_t model_version = 0;
  std::vector<cw::PlaneRecord> planes;
};

struct wallar_client {
  int fd = -1;
  const cw::SharedPoseBlock* shm = nullptr;
  std::vector<std::uint8_t> in;
  std::deque<wallar_event> events;
  std::map<std::uint32_t, cw::PlaneRecord> planes;
  std::uint64_t model_version = 0;
  std::int32_t tracking = WALLAR_TRACKING_NONE;
  bool closed = false;
  bool disconnect_reported = false;
};

namespace {

constexpr std::int64_t kNsPerS = 1000000000;
constexpr std::int64_t kMaxExtrapolateNs = 100000000;  // position: at most 100 ms ahead
constexpr std::int64_t kTrackedWithinNs = 200000000;   // further from the pose: not tracked

void set_error(char* error, std::size_t size, const std::string& text) {
  if (error == nullptr || size == 0) return;
  std::snprintf(error, size, "%s", text.c_str());
}

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::int64_t{ts.tv_sec} * kNsPerS + ts.tv_nsec;
}

// Quaternions as (x, y, z, w).
struct Quat {
  double x = 0, y = 0, z = 0, w = 1;
};
Quat mul(const Quat& a, const Quat& b) {
  return {
      a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y, a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
      a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w, a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z};
}
Quat exp_rotation(const double omega[3], double dt_s) {
  const double ax = omega[0] * dt_s, ay = omega[1] * dt_s, az = omega[2] * dt_s;
  const double angle = std::sqrt(ax * ax + ay * ay + az * az);
  if (angle < 1e-12) return {};
  const double s = std::sin(angle / 2) / angle;
  return {ax * s, ay * s, az * s, std::cos(angle / 2)};
}
// The rotation `q` scaled by `f` in [0, 1] (slerp from identity).
Quat scaled(const Quat& q, double f) {
  Quat a = q;
  if (a.w < 0) a = {-a.x, -a.y, -a.z, -a.w};
  const double s = std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
  if (s < 1e-12) return {};
  const double angle = 2 * std::atan2(s, a.w) * f;
  const double k = std::sin(angle / 2) / s;
  return {a.x * k, a.y * k, a.z * k, std::cos(angle / 2)};
}
Quat normalized(const Quat& q) {
  const double n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return n > 0 ? Quat{q.x / n, q.y / n, q.z / n, q.w / n} : Quat{};
}
Quat quat_of(const double xyzw[4]) { return {xyzw[0], xyzw[1], xyzw[2], xyzw[3]}; }

bool read_pose(const cw::SharedPoseBlock* shm, cw::PosePayload& out) {
  for (int attempt = 0; attempt < 100000; ++attempt) {
    if (cw::try_read_shared_pose(shm, out)) return true;
    if (attempt > 64) std::this_thread::yield();
  }
  return false;
}

void push_plane_events(wallar_client& c, const cw::PlaneBatch& batch) {
  // A full set replaces ours: what it lacks is removed.
  if ((batch.flags & cw::kPlanesFull) != 0) {
    for (auto it = c.planes.begin(); it != c.planes.end();) {
      const bool kept = std::any_of(batch.planes.begin(), batch.planes.end(),
                                    [&](const cw::PlaneRecord& p) { return p.id == it->first; });
      if (kept) {
        ++it;
        continue;
      }
      c.events.push_back(
          {WALLAR_EVENT_PLANE_REMOVED, it->first, 0, 0, batch.t_ns, batch.model_version});
      it = c.planes.erase(it);
    }
  }
  for (const cw::PlaneRecord& p : batch.planes) {
    wallar_event e{};
    e.plane_id = p.id;
    e.t_ns = batch.t_ns;
    e.model_version = batch.model_version;
    if (p.change == cw::PlaneChange::kRemoved) {
      e.type = WALLAR_EVENT_PLANE_REMOVED;
      e.subsumed_by = p.subsumed_by;
      c.planes.erase(p.id);
    } else {
      const auto old = c.planes.find(p.id);
      if (old != c.planes.end() && old->second.change_count == p.change_count &&
          (batch.flags & cw::kPlanesFull) != 0) {
        continue;  // a resync's plane we have as it is
      }
      e.type = old == c.planes.end() ? WALLAR_EVENT_PLANE_ADDED : WALLAR_EVENT_PLANE_UPDATED;
      c.planes[p.id] = p;
    }
    c.events.push_back(e);
  }
  c.model_version = batch.model_version;
}

// Parses whole messages from c.in; false on a malformed one (the connection is then unusable).
bool parse_input(wallar_client& c) {
  std::size_t at = 0;
  while (c.in.size() - at >= cw::kHeaderBytes) {
    const cw::Header h = cw::parse_header(c.in.data() + at);
    if (h.body_bytes > cw::kMaxServerBody) return false;
    if (c.in.size() - at < cw::kHeaderBytes + h.body_bytes) break;
    const std::uint8_t* body = c.in.data() + at + cw::kHeaderBytes;
    if (h.type == cw::MsgType::kPlanes) {
      const auto batch = cw::parse_planes(body, h.body_bytes, h.flags);
      if (!batch) return false;
      push_plane_events(c, *batch);
    } else if (h.type == cw::MsgType::kTracking) {
      if (h.body_bytes != 9) return false;
      std::int64_t t_ns = 0;
      std::memcpy(&t_ns, body, 8);
      c.tracking = body[8];
      c.events.push_back({WALLAR_EVENT_TRACKING_CHANGED, 0, 0, c.tracking, t_ns, 0});
    } else {
      return false;
    }
    at += cw::kHeaderBytes + h.body_bytes;
  }
  c.in.erase(c.in.begin(), c.in.begin() + static_cast<std::ptrdiff_t>(at));
  return true;
}

// Reads what the socket holds; false once it is closed.
bool drain_socket(wallar_client& c) {
  std::uint8_t buf[65536];
  for (;;) {
    const ssize_t n = recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n > 0) {
      c.in.insert(c.in.end(), buf, buf + n);
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
    if (n < 0 && errno == EINTR) continue;
    parse_input(c);
    return false;  // closed (0) or failed
  }
  return parse_input(c);
}

// Reads exactly one message (blocking, with a timeout): the answer to the hello.
bool read_answer(int fd, std::vector<std::uint8_t>& msg, int& memfd, std::string& error) {
  pollfd p{fd, POLLIN, 0};
  if (poll(&p, 1, 5000) <= 0) {
    error = "no answer from the firmware within 5 s";
    return false;
  }
  std::uint8_t buf[4096];
  cw::FdMessage m(buf, sizeof buf);
  msghdr& mh = m.header;
  const ssize_t n = recvmsg(fd, &mh, MSG_CMSG_CLOEXEC);
  if (n <= 0) {
    error = n == 0 ? "the firmware closed the connection without an answer"
                   : std::string("recvmsg: ") + std::strerror(errno);
    return false;
  }
  for (cmsghdr* cm = CMSG_FIRSTHDR(&mh); cm != nullptr; cm = CMSG_NXTHDR(&mh, cm)) {
    if (cm->cmsg_level == SOL_SOCKET && cm->cmsg_type == SCM_RIGHTS) {
      std::memcpy(&memfd, CMSG_DATA(cm), sizeof(int));
    }
  }
  msg.assign(buf, buf + n);
  return true;
}

}  // namespace

extern "C" {

int wallar_client_connect(const char* path, const char* app_name, wallar_client** out, char* error,
                          size_t error_size) {
  if (out == nullptr || path == nullptr) {
    set_error(error, error_size, "wallar_client_connect: path and out must not be NULL");
    return -1;
  }
  *out = nullptr;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (std::strlen(path) == 0 || std::strlen(path) >= sizeof addr.sun_path) {
    set_error(error, error_size, std::string(path) + ": not a UNIX socket path (1..107 bytes)");
    return -1;
  }
  std::strcpy(addr.sun_path, path);
  const int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0 || connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    set_error(error, error_size, std::string(path) + ": cannot connect: " + std::strerror(errno));
    if (fd >= 0) close(fd);
    return -1;
  }
  const auto hello =
      cw::encode_hello(WALLAR_CLIENT_PROTOCOL_VERSION, app_name != nullptr ? app_name : "");
  if (send(fd, hello.data(), hello.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(hello.size())) {
    set_error(error, error_size,
              std::string(path) + ": cannot send the hello: " + std::strerror(errno));
    close(fd);
    return -1;
  }
  std::vector<std::uint8_t> msg;
  int memfd = -1;
  std::string why;
  if (!read_answer(fd, msg, memfd, why)) {
    set_error(error, error_size, std::string(path) + ": " + why);
    close(fd);
    return -1;
  }
  auto fail = [&](const std::string& text) {
    set_error(error, error_size, std::string(path) + ": " + text);
    if (memfd >= 0) close(memfd);
    close(fd);
    return -1;
  };
  if (msg.size() < cw::kHeaderBytes + 4) return fail("a short answer to the hello");
  const cw::Header h = cw::parse_header(msg.data());
  if (h.type == cw::MsgType::kRefused) {
    const std::size_t text_at = cw::kHeaderBytes + 4;
    const std::size_t end = std::min<std::size_t>(msg.size(), cw::kHeaderBytes + h.body_bytes);
    return fail("refused: " + std::string(msg.begin() + static_cast<std::ptrdiff_t>(text_at),
                                          msg.begin() + static_cast<std::ptrdiff_t>(end)));
  }
  if (h.type != cw::MsgType::kAccepted || msg.size() < cw::kHeaderBytes + 8 || memfd < 0) {
    return fail("not a wallar answer (no shared memory with it)");
  }
  std::uint32_t shm_bytes = 0;
  std::memcpy(&shm_bytes, msg.data() + cw::kHeaderBytes + 4, 4);
  if (shm_bytes < sizeof(cw::SharedPoseBlock)) return fail("a shared-memory block too small");
  void* map = mmap(nullptr, shm_bytes, PROT_READ, MAP_SHARED, memfd, 0);
  close(memfd);
  memfd = -1;
  if (map == MAP_FAILED) return fail(std::string("mmap: ") + std::strerror(errno));
  auto* shm = static_cast<const cw::SharedPoseBlock*>(map);
  if (!cw::shared_pose_valid(shm)) {
    munmap(map, shm_bytes);
    return fail("the shared pose's layout is not this library's");
  }
  auto* c = new (std::nothrow) wallar_client;
  if (c == nullptr) {
    munmap(map, shm_bytes);
    return fail("out of memory");
  }
  c->fd = fd;
  c->shm = shm;
  // Bytes after the answer (the first planes) came in the same read.
  const std::size_t used = cw::kHeaderBytes + h.body_bytes;
  if (msg.size() > used) c->in.assign(msg.begin() + static_cast<std::ptrdiff_t>(used), msg.end());
  parse_input(*c);
  *out = c;
  return 0;
}

void wallar_client_disconnect(wallar_client* client) {
  if (client == nullptr) return;
  if (client->shm != nullptr) {
    munmap(const_cast<cw::SharedPoseBlock*>(client->shm), cw::kShmBytes);
  }
  if (client->fd >= 0) close(client->fd);
  delete client;
}

int wallar_client_fd(const wallar_client* client) { return client != nullptr ? client->fd : -1; }

int64_t wallar_client_now_ns(const wallar_client* client) {
  cw::PosePayload p;
  if (client == nullptr || !read_pose(client->shm, p)) return monotonic_ns();
  return monotonic_ns() + p.sensor_minus_monotonic_ns;
}

int wallar_client_view(const wallar_client* client, double q_body_view_xyzw[4],
                       double p_body_view_m[3]) {
  cw::PosePayload p;
  if (client == nullptr || q_body_view_xyzw == nullptr || p_body_view_m == nullptr ||
      !read_pose(client->shm, p)) {
    return -1;
  }
  for (int i = 0; i < 4; ++i) q_body_view_xyzw[i] = p.q_body_view_xyzw[i];
  for (int i = 0; i < 3; ++i) p_body_view_m[i] = p.p_body_view_m[i];
  return 0;
}

int wallar_client_locate(const wallar_client* client, int64_t t_ns, wallar_pose* out) {
  if (client == nullptr || out == nullptr) return -1;
  cw::PosePayload p;
  if (!read_pose(client->shm, p)) return -1;
  *out = wallar_pose{};
  out->t_ns = t_ns;
  out->q_world_body_xyzw[3] = 1.0;
  out->tracking = p.tracking;
  out->t_pose_ns = p.t_pose_ns;
  out->t_imu_ns = p.t_imu_ns;
  out->epoch = p.epoch;
  if (p.has_pose == 0 || p.tracking == WALLAR_TRACKING_NONE ||
      p.tracking == WALLAR_TRACKING_INITIALISING) {
    return 0;
  }
  // Orientation: the pose, the gyro's rotation since (up to t_imu), the newest rate beyond.
  const Quat q_world_pose = quat_of(p.q_world_body_xyzw);
  const Quat q_pose_imu = quat_of(p.q_pose_imu_xyzw);
  Quat q;
  if (t_ns >= p.t_imu_ns) {
    const double ahead_s =
        static_cast<double>(std::min(t_ns - p.t_imu_ns, kMaxExtrapolateNs)) / kNsPerS;
    q = mul(mul(q_world_pose, q_pose_imu), exp_rotation(p.omega_body_rad_s, ahead_s));
  } else if (t_ns >= p.t_pose_ns && p.t_imu_ns > p.t_pose_ns) {
    const double f =
        static_cast<double>(t_ns - p.t_pose_ns) / static_cast<double>(p.t_imu_ns - p.t_pose_ns);
    q = mul(q_world_pose, scaled(q_pose_imu, f));
  } else {
    const double back_s =
        static_cast<double>(std::max(t_ns - p.t_pose_ns, -kMaxExtrapolateNs)) / kNsPerS;
    q = mul(q_world_pose, exp_rotation(p.omega_body_rad_s, back_s));
  }
  q = normalized(q);
  out->q_world_body_xyzw[0] = q.x;
  out->q_world_body_xyzw[1] = q.y;
  out->q_world_body_xyzw[2] = q.z;
  out->q_world_body_xyzw[3] = q.w;
  const std::int64_t dt_ns = std::clamp(t_ns - p.t_pose_ns, -kMaxExtrapolateNs, kMaxExtrapolateNs);
  for (int i = 0; i < 3; ++i) {
    out->p_world_body_m[i] =
        p.p_world_body_m[i] + p.v_world_body_m_s[i] * static_cast<double>(dt_ns) / kNsPerS;
  }
  out->flags = WALLAR_POSE_ORIENTATION_VALID | WALLAR_POSE_POSITION_VALID;
  if (p.tracking == WALLAR_TRACKING_TRACKING) {
    if (std::llabs(t_ns - p.t_imu_ns) <= kTrackedWithinNs)
      out->flags |= WALLAR_POSE_ORIENTATION_TRACKED;
    if (std::llabs(t_ns - p.t_pose_ns) <= kTrackedWithinNs)
      out->flags |= WALLAR_POSE_POSITION_TRACKED;
  }
  return 0;
}

int wallar_client_poll_events(wallar_client* client, int timeout_ms, wallar_event* events,
                              int max) {
  if (client == nullptr || (events == nullptr && max > 0)) return -1;
  if (!client->closed && client->events.empty() && timeout_ms != 0) {
    pollfd p{client->fd, POLLIN, 0};
    (void)poll(&p, 1, timeout_ms);
  }
  if (!client->closed && !drain_socket(*client)) client->closed = true;
  if (client->closed && client->events.empty()) {
    if (client->disconnect_reported) return -1;
    if (max < 1) return 0;
    client->disconnect_reported = true;
    events[0] = wallar_event{};
    events[0].type = WALLAR_EVENT_DISCONNECTED;
    return 1;
  }
  int n = 0;
  while (n < max && !client->events.empty()) {
    events[n++] = client->events.front();
    client->events.pop_front();
  }
  return n;
}

int32_t wallar_client_tracking(const wallar_client* client) {
  return client != nullptr ? client->tracking : WALLAR_TRACKING_NONE;
}

int wallar_client_begin_planes(wallar_client* client, wallar_planes** out) {
  if (client == nullptr || out == nullptr) return -1;
  *out = nullptr;
  auto* s = new (std::nothrow) wallar_planes;
  if (s == nullptr) return -1;
  try {
    s->model_version = client->model_version;
    s->planes.reserve(client->planes.size());
    for (const auto& [id, p] : client->planes) s->planes.push_back(p);
  } catch (const std::bad_alloc&) {
    delete s;
    return -1;
  }
  *out = s;
  return 0;
}

size_t wallar_planes_count(const wallar_planes* planes) {
  return planes != nullptr ? planes->planes.size() : 0;
}

uint64_t wallar_planes_model_version(const wallar_planes* planes) {
  return planes != nullptr ? planes->model_version : 0;
}

int wallar_planes_get(const wallar_planes* planes, size_t index, wallar_plane* out) {
  if (planes == nullptr || out == nullptr || index >= planes->planes.size()) return -1;
  const cw::PlaneRecord& p = planes->planes[index];
  *out = wallar_plane{};
  out->id = p.id;
  out->orientation = static_cast<int32_t>(p.orientation);
  out->label = static_cast<int32_t>(p.semantic);
  out->change_count = p.change_count;
  std::copy(std::begin(p.p_world_plane_m), std::end(p.p_world_plane_m), out->p_world_plane_m);
  std::copy(std::begin(p.q_world_plane_xyzw), std::end(p.q_world_plane_xyzw),
            out->q_world_plane_xyzw);
  std::copy(std::begin(p.extent_m), std::end(p.extent_m), out->extent_m);
  out->vertex_count = static_cast<uint32_t>(p.polygon_m.size());
  return 0;
}

size_t wallar_planes_polygon(const wallar_planes* planes, size_t index, double* xy,
                             size_t capacity) {
  if (planes == nullptr || index >= planes->planes.size()) return 0;
  const auto& poly = planes->planes[index].polygon_m;
  for (std::size_t i = 0; i < poly.size() && i < capacity && xy != nullptr; ++i) {
    xy[2 * i] = poly[i][0];
    xy[2 * i + 1] = poly[i][1];
  }
  return poly.size();
}

void wallar_planes_end(wallar_planes* planes) { delete planes; }

}  // extern "C"
