// SPDX-License-Identifier: Apache-2.0
/// @file client_server.cpp
/// @brief The client API server: the shared pose, planes with OpenXR semantics, the socket.
#include "wallar/firmware/appliance/client_server.hpp"

#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <deque>
#include <fstream>
#include <sstream>

#include "wallar/core/error.hpp"
#include "wallar/firmware/world_frames.hpp"

namespace wallar::firmware {
namespace cw = client_wire;
namespace {

constexpr double kDegToRad = M_PI / 180.0;

std::string errno_text() { return std::strerror(errno); }

cw::Tracking tracking_of(std::uint8_t dsp_state) {
  switch (static_cast<dsp::TrackingState>(dsp_state)) {
    case dsp::TrackingState::kInitialising:
      return cw::Tracking::kInitialising;
    case dsp::TrackingState::kTracking:
      return cw::Tracking::kTracking;
    case dsp::TrackingState::kLost:
      return cw::Tracking::kLost;
  }
  return cw::Tracking::kNone;
}

// Inside the polygon, or within `margin` of an edge.
bool near_polygon(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& q,
                  double margin) {
  bool inside = false;
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > q.y()) != (b.y() > q.y()) &&
        q.x() < (b.x() - a.x()) * (q.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
    const Eigen::Vector2d ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0 ? std::clamp((q - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    nearest = std::min(nearest, (a + t * ab - q).norm());
  }
  return inside || nearest <= margin;
}

Eigen::Vector3d centroid_world(const Wall& w) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < w.extent_uv_m.size(); ++i) c += w.corner(i);
  return w.extent_uv_m.empty() ? w.origin : Eigen::Vector3d(c / double(w.extent_uv_m.size()));
}

bool same_geometry(const cw::PlaneRecord& a, const cw::PlaneRecord& b) {
  return a.semantic == b.semantic && a.orientation == b.orientation &&
         std::equal(std::begin(a.p_world_plane_m), std::end(a.p_world_plane_m),
                    std::begin(b.p_world_plane_m)) &&
         std::equal(std::begin(a.q_world_plane_xyzw), std::end(a.q_world_plane_xyzw),
                    std::begin(b.q_world_plane_xyzw)) &&
         std::equal(std::begin(a.extent_m), std::end(a.extent_m), std::begin(b.extent_m)) &&
         a.polygon_m == b.polygon_m;
}

}  // namespace

// ---- shared pose ---------------------------------------------------------------------------

SharedPosePublisher::SharedPosePublisher(cw::SharedPoseBlock* block, const SE3d& T_out_world,
                                         const SE3d& T_body_view)
    : writer_(block), T_out_world_(T_out_world) {
  const Eigen::Quaterniond q(T_body_view.linear());
  const double qv[4] = {q.x(), q.y(), q.z(), q.w()};
  for (int i = 0; i < 4; ++i) value_.q_body_view_xyzw[i] = qv[i];
  for (int i = 0; i < 3; ++i) value_.p_body_view_m[i] = T_body_view.translation()[i];
  if (writer_.attached()) writer_.store(value_);
}

void SharedPosePublisher::on_pose(TimeNs t_ns, const SE3d& T_world_body, cw::Tracking state,
                                  std::uint32_t epoch, DurationNs sensor_minus_monotonic_ns) {
  if (!writer_.attached()) return;
  const SE3d T = T_out_world_ * T_world_body;
  const Eigen::Vector3d p = T.translation();
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  const bool tracked = state == cw::Tracking::kTracking;
  if (tracked && t_prev_ns_ >= 0 && epoch == epoch_prev_ && t_ns > t_prev_ns_) {
    v = (p - p_prev_) / ns_to_s(t_ns - t_prev_ns_);
  }
  if (tracked) {
    p_prev_ = p;
    t_prev_ns_ = t_ns;
  } else {
    t_prev_ns_ = -1;
  }
  epoch_prev_ = epoch;
  const Eigen::Quaterniond q(T.linear());
  value_.t_pose_ns = t_ns;
  value_.q_world_body_xyzw[0] = q.x();
  value_.q_world_body_xyzw[1] = q.y();
  value_.q_world_body_xyzw[2] = q.z();
  value_.q_world_body_xyzw[3] = q.w();
  for (int i = 0; i < 3; ++i) {
    value_.p_world_body_m[i] = p[i];
    value_.v_world_body_m_s[i] = v[i];
  }
  q_pose_imu_ = Eigen::Quaterniond::Identity();
  value_.t_imu_ns = t_ns;
  value_.q_pose_imu_xyzw[0] = value_.q_pose_imu_xyzw[1] = value_.q_pose_imu_xyzw[2] = 0.0;
  value_.q_pose_imu_xyzw[3] = 1.0;
  value_.sensor_minus_monotonic_ns = sensor_minus_monotonic_ns;
  value_.epoch = epoch;
  value_.tracking = static_cast<std::uint8_t>(state);
  value_.has_pose = 1;
  ++value_.updates;
  writer_.store(value_);
}

void SharedPosePublisher::on_imu(TimeNs t_ns, const Eigen::Vector3d& omega_body_rad_s) {
  if (!writer_.attached()) return;
  if (value_.has_pose != 0 && t_ns > value_.t_imu_ns) {
    // The rotation over (t_imu, t]: the newest rate held over the interval.
    const Eigen::Vector3d angle = omega_body_rad_s * ns_to_s(t_ns - value_.t_imu_ns);
    const double a = angle.norm();
    if (a > 0) q_pose_imu_ = (q_pose_imu_ * Eigen::Quaterniond(Eigen::AngleAxisd(a, angle / a)));
    q_pose_imu_.normalize();
    value_.t_imu_ns = t_ns;
  } else if (value_.has_pose == 0) {
    value_.t_imu_ns = t_ns;
  }
  value_.q_pose_imu_xyzw[0] = q_pose_imu_.x();
  value_.q_pose_imu_xyzw[1] = q_pose_imu_.y();
  value_.q_pose_imu_xyzw[2] = q_pose_imu_.z();
  value_.q_pose_imu_xyzw[3] = q_pose_imu_.w();
  for (int i = 0; i < 3; ++i) value_.omega_body_rad_s[i] = omega_body_rad_s[i];
  value_.has_imu = 1;
  ++value_.updates;
  writer_.store(value_);
}

// ---- planes --------------------------------------------------------------------------------

cw::PlaneRecord plane_record(const Wall& w, const std::optional<Eigen::Vector3d>& down_world,
                             bool gravity_aligned) {
  cw::PlaneRecord r;
  r.id = w.id;
  const Eigen::Vector3d n = w.plane.n.normalized();
  // The plane frame: x along u, z along n, y = z x x (right-handed even if u x v = -n).
  Eigen::Vector3d x = (w.u - w.u.dot(n) * n).normalized();
  if (!x.allFinite() || x.norm() < 0.5) x = n.unitOrthogonal();
  const Eigen::Vector3d y = n.cross(x);
  Eigen::Matrix3d R;
  R << x, y, n;
  // The polygon's corners in (x, y), about its bounding box's centre.
  std::vector<Eigen::Vector2d> xy;
  xy.reserve(w.extent_uv_m.size());
  Eigen::Vector2d lo(std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (std::size_t i = 0; i < w.extent_uv_m.size(); ++i) {
    const Eigen::Vector3d d = w.corner(i) - w.origin;
    const Eigen::Vector2d q(d.dot(x), d.dot(y));
    xy.push_back(q);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  if (!xy.empty()) centre = 0.5 * (lo + hi);
  // In the extent's own plane (through its origin), so the corners come back exactly.
  const Eigen::Vector3d c = w.origin + centre.x() * x + centre.y() * y;
  double area2 = 0.0;
  for (std::size_t i = 0; i < xy.size(); ++i) {
    const Eigen::Vector2d& a = xy[i];
    const Eigen::Vector2d& b = xy[(i + 1) % xy.size()];
    area2 += a.x() * b.y() - b.x() * a.y();
  }
  if (area2 < 0) std::reverse(xy.begin(), xy.end());  // counter-clockwise seen from +z
  r.polygon_m.reserve(xy.size());
  for (const Eigen::Vector2d& q : xy)
    r.polygon_m.push_back({q.x() - centre.x(), q.y() - centre.y()});
  if (!xy.empty()) {
    r.extent_m[0] = hi.x() - lo.x();
    r.extent_m[1] = hi.y() - lo.y();
  }
  const Eigen::Quaterniond q(R);
  r.q_world_plane_xyzw[0] = q.x();
  r.q_world_plane_xyzw[1] = q.y();
  r.q_world_plane_xyzw[2] = q.z();
  r.q_world_plane_xyzw[3] = q.w();
  for (int i = 0; i < 3; ++i) r.p_world_plane_m[i] = c[i];
  // Orientation: against gravity when known (within 10 degrees), else the surface's kind when
  // the search that found it knew down; a 3-D search's surfaces are of unknown orientation (its
  // kWall is any plane: the floor too).
  if (down_world) {
    const double up = -n.dot(down_world->normalized());
    const double tol = std::sin(10.0 * kDegToRad);
    if (up > std::cos(10.0 * kDegToRad)) {
      r.orientation = cw::Orientation::kHorizontalUpward;
    } else if (up < -std::cos(10.0 * kDegToRad)) {
      r.orientation = cw::Orientation::kHorizontalDownward;
    } else if (std::abs(up) < tol) {
      r.orientation = cw::Orientation::kVertical;
    } else {
      r.orientation = cw::Orientation::kArbitrary;
    }
  } else if (!gravity_aligned) {
    r.orientation = cw::Orientation::kArbitrary;
  } else {
    r.orientation = w.kind == SurfaceKind::kFloor     ? cw::Orientation::kHorizontalUpward
                    : w.kind == SurfaceKind::kCeiling ? cw::Orientation::kHorizontalDownward
                                                      : cw::Orientation::kVertical;
  }
  if (!gravity_aligned) {
    r.semantic = cw::Semantic::kUnknown;  // whatever its orientation now: the search did not know
    return r;
  }
  switch (w.kind) {
    case SurfaceKind::kFloor:
      r.semantic = r.orientation == cw::Orientation::kHorizontalUpward ? cw::Semantic::kFloor
                                                                       : cw::Semantic::kUnknown;
      break;
    case SurfaceKind::kCeiling:
      r.semantic = r.orientation == cw::Orientation::kHorizontalDownward ? cw::Semantic::kCeiling
                                                                         : cw::Semantic::kUnknown;
      break;
    case SurfaceKind::kWall:
      r.semantic = r.orientation == cw::Orientation::kVertical ? cw::Semantic::kWall
                                                               : cw::Semantic::kUnknown;
      break;
  }
  return r;
}

bool subsumes(const Wall& survivor, const Wall& absorbed) {
  const double cos_angle = survivor.plane.n.normalized().dot(absorbed.plane.n.normalized());
  if (cos_angle < std::cos(ClientPlanes::kSubsumeAngleDeg * kDegToRad)) return false;
  const Eigen::Vector3d c = centroid_world(absorbed);
  if (std::abs(survivor.plane.signed_distance(c)) > ClientPlanes::kSubsumeDistanceM) return false;
  if (survivor.extent_uv_m.size() < 3) return false;
  const Eigen::Vector3d d = c - survivor.origin;
  return near_polygon(survivor.extent_uv_m, {d.dot(survivor.u), d.dot(survivor.v)},
                      ClientPlanes::kSubsumeMarginM);
}

cw::PlaneBatch ClientPlanes::update(const WallModel& model,
                                    const std::optional<Eigen::Vector3d>& down_world) {
  cw::PlaneBatch batch;
  batch.model_version = model_version_ = model.version;
  batch.t_ns = t_ns_ = model.t_ns;
  std::map<std::uint32_t, Kept> next;
  for (const Wall& w : model.walls) {
    cw::PlaneRecord r = plane_record(w, down_world, model.gravity_aligned);
    const auto old = planes_.find(w.id);
    if (old == planes_.end()) {
      r.change = cw::PlaneChange::kAdded;
      batch.planes.push_back(r);
    } else {
      r.change_count = old->second.record.change_count;
      if (!same_geometry(old->second.record, r)) {
        ++r.change_count;
        r.change = cw::PlaneChange::kUpdated;
        batch.planes.push_back(r);
      }
    }
    next[w.id] = Kept{r, w};
  }
  for (const auto& [id, kept] : planes_) {
    if (next.count(id) != 0) continue;
    cw::PlaneRecord r = kept.record;
    r.change = cw::PlaneChange::kRemoved;
    r.polygon_m.clear();
    // The merge rule: the largest surviving plane it lies on absorbed it.
    std::size_t best_size = 0;
    for (const Wall& w : model.walls) {
      if (subsumes(w, kept.wall) && w.inliers + 1 > best_size) {
        best_size = w.inliers + 1;
        r.subsumed_by = w.id;
      }
    }
    batch.planes.push_back(r);
  }
  planes_ = std::move(next);
  return batch;
}

cw::PlaneBatch ClientPlanes::full() const {
  cw::PlaneBatch batch;
  batch.flags = cw::kPlanesFull;
  batch.model_version = model_version_;
  batch.t_ns = t_ns_;
  for (const auto& [id, kept] : planes_) {
    batch.planes.push_back(kept.record);
    batch.planes.back().change = cw::PlaneChange::kAdded;
  }
  return batch;
}

// ---- the server ----------------------------------------------------------------------------

struct ClientServer::Client {
  int fd = -1;
  TimeNs connected_ns = 0;
  bool accepted = false;
  bool closing = false;       //!< refused: close once the answer is out
  bool needs_resync = false;  //!< updates were dropped: send the whole set when it fits
  std::vector<std::uint8_t> in;
  std::deque<std::vector<std::uint8_t>> out;
  std::size_t out_offset = 0;  //!< bytes of out.front() sent
  std::size_t out_bytes = 0;
  pid_t pid = 0;
  uid_t uid = 0;
  gid_t gid = 0;
};

ClientServer::ClientServer(const ClientConfig& config, const SE3d& T_out_world,
                           const SE3d& T_body_view, const Seqlock<PoseSnapshot>& pose,
                           TripleBuffer<WallModel>& walls, ClientServerOptions options)
    : config_(config),
      options_(options),
      T_out_world_(T_out_world),
      T_body_view_(T_body_view),
      pose_(pose),
      walls_(walls) {
  const std::string& path = config_.socket;
  const std::string what = "client.socket " + path + ": ";
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof addr.sun_path) {
    throw InputError(what + "a UNIX socket's path must be 1.." +
                     std::to_string(sizeof addr.sun_path - 1) + " bytes");
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  const std::size_t slash = path.rfind('/');
  if (slash != std::string::npos && slash > 0) {
    const std::string dir = path.substr(0, slash);
    struct stat st {};
    if (::stat(dir.c_str(), &st) != 0 && ::mkdir(dir.c_str(), 0755) != 0) {
      throw InputError(what + "cannot create its folder: " + errno_text());
    }
  }
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) throw InputError(what + "exists and is not a socket");
    // A socket file: another server's (refuse), or a stale one from a run that died (replace).
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool live =
        probe >= 0 && ::connect(probe, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    if (probe >= 0) ::close(probe);
    if (live) throw InputError(what + "another server listens on it (a second wallar run?)");
    ::unlink(path.c_str());
  }
  listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (listen_fd_ < 0) throw InputError(what + "socket: " + errno_text());
  // Created with no access for others; the mode is set once the group is.
  const mode_t old_mask = ::umask(0177);
  const int bound = ::bind(listen_fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr);
  const int bind_errno = errno;
  ::umask(old_mask);
  if (bound != 0) {
    ::close(listen_fd_);
    throw InputError(what + "cannot bind: " + std::strerror(bind_errno));
  }
  if (!config_.group.empty()) {
    group grp{};
    group* found = nullptr;
    std::vector<char> buf(16384);
    if (::getgrnam_r(config_.group.c_str(), &grp, buf.data(), buf.size(), &found) == 0 &&
        found != nullptr) {
      gid_ = found->gr_gid;
      has_group_ = ::chown(path.c_str(), static_cast<uid_t>(-1), gid_) == 0;
      if (!has_group_) group_note_ = "cannot give it group " + config_.group + ": " + errno_text();
    } else {
      group_note_ = "no group " + config_.group + " on this system: the owner only";
    }
  }
  if (::chmod(path.c_str(), config_.mode) != 0 || ::listen(listen_fd_, 16) != 0) {
    const std::string e = errno_text();
    ::close(listen_fd_);
    ::unlink(path.c_str());
    throw InputError(what + "cannot listen: " + e);
  }
  memfd_ = ::memfd_create("wallar-pose", MFD_CLOEXEC | MFD_ALLOW_SEALING);
  if (memfd_ < 0 || ::ftruncate(memfd_, cw::kShmBytes) != 0) {
    throw std::runtime_error("client API: memfd: " + errno_text());
  }
  shm_ = ::mmap(nullptr, cw::kShmBytes, PROT_READ | PROT_WRITE, MAP_SHARED, memfd_, 0);
  if (shm_ == MAP_FAILED) throw std::runtime_error("client API: mmap: " + errno_text());
    // Clients map it read-only: no new writable mapping, nor a resize, once sealed.
#ifdef F_SEAL_FUTURE_WRITE
  if (::fcntl(memfd_, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_FUTURE_WRITE) != 0)
#endif
    (void)::fcntl(memfd_, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW);
  (void)::fcntl(memfd_, F_ADD_SEALS, F_SEAL_SEAL);
  publisher_ =
      SharedPosePublisher(static_cast<cw::SharedPoseBlock*>(shm_), T_out_world_, T_body_view_);
  wake_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (wake_fd_ < 0) throw std::runtime_error("client API: eventfd: " + errno_text());
  clients_.reserve(static_cast<std::size_t>(options_.max_clients));
  msg_.reserve(64 * 1024);
}

ClientServer::~ClientServer() {
  stop(0);
  for (auto& c : clients_) ::close(c->fd);
  clients_.clear();
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    ::unlink(config_.socket.c_str());
  }
  if (shm_ != nullptr && shm_ != MAP_FAILED) ::munmap(shm_, cw::kShmBytes);
  if (memfd_ >= 0) ::close(memfd_);
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

std::string ClientServer::describe() const {
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", config_.mode);
  std::string d = "client API on " + config_.socket + " (mode " + mode;
  d += has_group_ ? ", group " + config_.group + ")" : "; " + group_note_ + ")";
  return d;
}

void ClientServer::start(ThreadSpec spec) {
  thread_ = std::make_unique<RtThread>(std::move(spec), [this] { loop(); });
}

void ClientServer::stop(DurationNs flush_ns) {
  flush_ns_.store(flush_ns, std::memory_order_relaxed);
  stop_.store(true, std::memory_order_release);
  if (wake_fd_ >= 0) {
    const std::uint64_t one = 1;
    (void)!::write(wake_fd_, &one, sizeof one);
  }
  if (thread_ && thread_->joinable()) thread_->join();
}

ClientServerCounters ClientServer::counters() const {
  ClientServerCounters c;
  c.accepted = accepted_.load(std::memory_order_relaxed);
  c.refused = refused_.load(std::memory_order_relaxed);
  c.malformed = malformed_.load(std::memory_order_relaxed);
  c.timeouts = timeouts_.load(std::memory_order_relaxed);
  c.dropped = dropped_.load(std::memory_order_relaxed);
  c.resyncs = resyncs_.load(std::memory_order_relaxed);
  c.sent_bytes = sent_bytes_.load(std::memory_order_relaxed);
  c.clients = clients_now_.load(std::memory_order_relaxed);
  c.plane_models = plane_models_.load(std::memory_order_relaxed);
  return c;
}

std::vector<std::pair<const char*, std::uint64_t>> ClientServer::counter_list() const {
  const ClientServerCounters c = counters();
  return {{"accepted", c.accepted},     {"refused", c.refused}, {"malformed", c.malformed},
          {"timeouts", c.timeouts},     {"dropped", c.dropped}, {"resyncs", c.resyncs},
          {"sent_bytes", c.sent_bytes}, {"clients", c.clients}, {"plane_models", c.plane_models}};
}

void ClientServer::loop() {
  while (!stop_.load(std::memory_order_acquire)) step(false);
  // The final wall model (the supervisor's last search ran before stop()), then a short flush.
  step(true);
  const TimeNs deadline = monotonic_now_ns() + flush_ns_.load(std::memory_order_relaxed);
  for (;;) {
    std::vector<pollfd> fds;
    std::vector<Client*> who;
    for (auto& c : clients_) {
      if (c->out_bytes > 0) {
        fds.push_back({c->fd, POLLOUT, 0});
        who.push_back(c.get());
      }
    }
    const TimeNs left = deadline - monotonic_now_ns();
    if (fds.empty() || left <= 0) break;
    if (::poll(fds.data(), fds.size(), static_cast<int>(left / kNsPerMs) + 1) <= 0) continue;
    for (std::size_t i = 0; i < fds.size(); ++i) {
      if ((fds[i].revents & (POLLERR | POLLHUP)) != 0) {
        close_client(*who[i], nullptr);
      } else if ((fds[i].revents & POLLOUT) != 0) {
        flush(*who[i]);
      }
    }
    std::erase_if(clients_, [](const auto& c) { return c->fd < 0; });
  }
  for (auto& c : clients_) close_client(*c, nullptr);
  clients_.clear();
  clients_now_.store(0, std::memory_order_relaxed);
}

void ClientServer::step(bool final_pass) {
  wakeups_.fetch_add(1, std::memory_order_relaxed);
  if (!final_pass) {
    std::vector<pollfd> fds;
    fds.reserve(clients_.size() + 2);
    fds.push_back({wake_fd_, POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (auto& c : clients_) {
      fds.push_back({c->fd, static_cast<short>(POLLIN | (c->out_bytes > 0 ? POLLOUT : 0)), 0});
    }
    const int n =
        ::poll(fds.data(), fds.size(), static_cast<int>(options_.loop_period_ns / kNsPerMs));
    if (n > 0) {
      if ((fds[1].revents & POLLIN) != 0) accept_clients();
      for (std::size_t i = 2; i < fds.size(); ++i) {
        Client& c = *clients_[i - 2];
        if (c.fd < 0) continue;
        if ((fds[i].revents & POLLIN) != 0) read_client(c);
        if (c.fd >= 0 && (fds[i].revents & POLLOUT) != 0) flush(c);
        if (c.fd >= 0 && (fds[i].revents & (POLLERR | POLLHUP)) != 0 &&
            (fds[i].revents & POLLIN) == 0) {
          close_client(c, nullptr);
        }
      }
    }
    const TimeNs now = monotonic_now_ns();
    for (auto& c : clients_) {
      if (c->fd >= 0 && !c->accepted && now - c->connected_ns > options_.hello_timeout_ns)
        close_client(*c, &timeouts_);
    }
  }
  // The tracking state (the pose seqlock: any number of readers).
  const PoseSnapshot p = pose_.load();
  if (p.t_ns > 0) {
    const auto state = static_cast<std::uint8_t>(tracking_of(p.state));
    if (state != tracking_sent_) {
      tracking_sent_ = state;
      cw::encode_tracking(msg_, p.t_ns, static_cast<cw::Tracking>(state));
      for (auto& c : clients_) {
        if (c->fd >= 0 && c->accepted) queue(*c, msg_, false);
      }
    }
  }
  // A new wall model: its changes to every client, in the API's world.
  if (walls_.refresh()) {
    std::optional<Eigen::Vector3d> down;
    if (const auto d = down_of(p)) down = T_out_world_.linear() * *d;
    const cw::PlaneBatch batch = planes_.update(transformed(walls_.front(), T_out_world_), down);
    plane_models_.fetch_add(1, std::memory_order_relaxed);
    if (!batch.planes.empty()) {
      cw::encode_planes(msg_, batch);
      for (auto& c : clients_) {
        if (c->fd >= 0 && c->accepted) queue(*c, msg_, true);
      }
    }
  }
  // Clients that lost updates get the whole set once it fits.
  for (auto& c : clients_) {
    if (c->fd < 0 || !c->needs_resync) continue;
    cw::encode_planes(msg_, planes_.full());
    if (c->out_bytes > 0 && c->out_bytes + msg_.size() > options_.max_queue_bytes) continue;
    c->needs_resync = false;
    resyncs_.fetch_add(1, std::memory_order_relaxed);
    queue(*c, msg_, false);
    if (tracking_sent_ != 0xff) {
      cw::encode_tracking(msg_, p.t_ns, static_cast<cw::Tracking>(tracking_sent_));
      queue(*c, msg_, false);
    }
  }
  for (auto& c : clients_) {
    if (c->fd >= 0 && c->out_bytes > 0) flush(*c);
  }
  std::erase_if(clients_, [](const auto& c) { return c->fd < 0; });
  clients_now_.store(clients_.size(), std::memory_order_relaxed);
}

void ClientServer::accept_clients() {
  for (;;) {
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;  // EAGAIN, or a connection gone before it was taken
    if (clients_.size() >= static_cast<std::size_t>(options_.max_clients)) {
      const auto m =
          cw::encode_answer(cw::MsgType::kRefused, cw::kProtocolVersion, 0,
                            "too many clients (" + std::to_string(options_.max_clients) + ")");
      (void)!::send(fd, m.data(), m.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
      ::close(fd);
      refused_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    auto c = std::make_unique<Client>();
    c->fd = fd;
    c->connected_ns = monotonic_now_ns();
    ucred cred{};
    socklen_t len = sizeof cred;
    if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) == 0) {
      c->pid = cred.pid;
      c->uid = cred.uid;
      c->gid = cred.gid;
    }
    clients_.push_back(std::move(c));
  }
}

void ClientServer::read_client(Client& c) {
  std::uint8_t buf[512];
  for (;;) {
    const ssize_t n = ::recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n == 0) {
      close_client(c, nullptr);  // the client hung up
      return;
    }
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) break;
      close_client(c, nullptr);
      return;
    }
    if (c.closing) continue;  // a refused client's further bytes are ignored
    c.in.insert(c.in.end(), buf, buf + n);
    while (c.in.size() >= cw::kHeaderBytes && c.fd >= 0) {
      const cw::Header h = cw::parse_header(c.in.data());
      if (h.body_bytes > cw::kMaxClientBody || h.type != cw::MsgType::kHello || c.accepted) {
        close_client(c, &malformed_);  // oversized, unknown, or a second hello
        return;
      }
      if (c.in.size() < cw::kHeaderBytes + h.body_bytes) break;
      hello(c, c.in.data() + cw::kHeaderBytes, h.body_bytes);
      c.in.erase(c.in.begin(), c.in.begin() + cw::kHeaderBytes + h.body_bytes);
      if (c.closing) return;
    }
  }
}

void ClientServer::hello(Client& c, const std::uint8_t* body, std::size_t n) {
  const cw::Hello h = cw::parse_hello(body, n);
  if (!h.error.empty()) {
    close_client(c, &malformed_);
    return;
  }
  std::string refusal;
  if (h.version != cw::kProtocolVersion) {
    refusal = "protocol version " + std::to_string(h.version) +
              " is not served: this wallar speaks version " + std::to_string(cw::kProtocolVersion) +
              " (use the libwallar-client it ships)";
  } else {
    // SO_PEERCRED: root, the firmware's own user, or a member of the socket's group.
    bool allowed = c.uid == 0 || c.uid == ::geteuid() || (has_group_ && c.gid == gid_);
    if (!allowed && has_group_ && c.pid > 0) {
      std::ifstream status("/proc/" + std::to_string(c.pid) + "/status");
      for (std::string line; std::getline(status, line);) {
        if (line.rfind("Groups:", 0) != 0) continue;
        std::istringstream groups(line.substr(7));
        for (unsigned g; groups >> g;) allowed = allowed || g == gid_;
      }
    }
    if (!allowed) {
      refusal = "uid " + std::to_string(c.uid) + " may not use the client API (group " +
                (has_group_ ? config_.group : std::string("none")) + ")";
    }
  }
  if (!refusal.empty()) {
    const auto m = cw::encode_answer(cw::MsgType::kRefused, cw::kProtocolVersion, 0, refusal);
    (void)!::send(c.fd, m.data(), m.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
    refused_.fetch_add(1, std::memory_order_relaxed);
    c.closing = true;
    close_client(c, nullptr);
    return;
  }
  // Accepted: the answer carries the memfd (SCM_RIGHTS); the first bytes on a fresh socket,
  // so its buffer takes them whole.
  const auto m = cw::encode_answer(cw::MsgType::kAccepted, cw::kProtocolVersion,
                                   static_cast<std::uint32_t>(cw::kShmBytes), "wallar");
  cw::FdMessage fm(const_cast<std::uint8_t*>(m.data()), m.size());
  msghdr& mh = fm.header;
  cmsghdr* cm = CMSG_FIRSTHDR(&mh);
  cm->cmsg_level = SOL_SOCKET;
  cm->cmsg_type = SCM_RIGHTS;
  cm->cmsg_len = CMSG_LEN(sizeof(int));
  std::memcpy(CMSG_DATA(cm), &memfd_, sizeof(int));
  if (::sendmsg(c.fd, &mh, MSG_DONTWAIT | MSG_NOSIGNAL) != static_cast<ssize_t>(m.size())) {
    close_client(c, nullptr);
    return;
  }
  c.accepted = true;
  accepted_.fetch_add(1, std::memory_order_relaxed);
  sent_bytes_.fetch_add(m.size(), std::memory_order_relaxed);
  // Its first state: every plane, and the tracking state.
  cw::encode_planes(msg_, planes_.full());
  queue(c, msg_, false);
  if (tracking_sent_ != 0xff) {
    cw::encode_tracking(msg_, pose_.load().t_ns, static_cast<cw::Tracking>(tracking_sent_));
    queue(c, msg_, false);
  }
}

void ClientServer::queue(Client& c, const std::vector<std::uint8_t>& msg, bool plane_update) {
  // After a drop, plane changes are not queued until the whole set went out again: a change
  // is relative to what the client has.
  // An empty queue takes any message (one larger than the bound too).
  const bool full = c.out_bytes > 0 && c.out_bytes + msg.size() > options_.max_queue_bytes;
  if ((plane_update && c.needs_resync) || full) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    c.needs_resync = true;
    return;
  }
  c.out.push_back(msg);
  c.out_bytes += msg.size();
}

void ClientServer::flush(Client& c) {
  while (!c.out.empty()) {
    const std::vector<std::uint8_t>& m = c.out.front();
    const ssize_t n =
        ::send(c.fd, m.data() + c.out_offset, m.size() - c.out_offset, MSG_DONTWAIT | MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;
      close_client(c, nullptr);
      return;
    }
    sent_bytes_.fetch_add(static_cast<std::uint64_t>(n), std::memory_order_relaxed);
    c.out_offset += static_cast<std::size_t>(n);
    if (c.out_offset == m.size()) {
      c.out_bytes -= m.size();
      c.out_offset = 0;
      c.out.pop_front();
    }
  }
}

void ClientServer::close_client(Client& c, std::atomic<std::uint64_t>* counter) {
  if (c.fd < 0) return;
  if (counter != nullptr) counter->fetch_add(1, std::memory_order_relaxed);
  ::close(c.fd);
  c.fd = -1;
  c.out.clear();
  c.out_bytes = 0;
}

}  // namespace wallar::firmware
