// SPDX-License-Identifier: Apache-2.0
/// @file wire.hpp
/// @brief The client protocol between `wallar run` (firmware/appliance/client_server.hpp) and
/// libwallar-client: message framing, the messages' encodings, and the shared-memory pose
/// (a seqlock in a memfd) with its writer and reader. One header, so both sides agree.
///
/// Framing (every message, both ways): a header of 8 bytes, little-endian: u32 body length,
/// u16 type, u16 flags; then the body. A client's message body is at most kMaxClientBody
/// bytes; anything longer, an unknown type or a message other than the first hello closes
/// that client (counted). Numbers in bodies are little-endian; doubles IEEE-754 binary64.
/// Protocol version kProtocolVersion; a hello with another version is refused with a message.
///
/// Shared pose: the server's memfd (passed with SCM_RIGHTS alongside the accepted message)
/// holds a SharedPoseBlock: a magic, the layout version, then a seqlock (sequence word,
/// payload words) over a PosePayload. Every word is accessed through std::atomic_ref<uint64_t>
/// (lock-free, so valid across processes): the writer makes the sequence odd (relaxed), stores
/// each word with release, and makes it even with release; a reader acquire-loads the
/// sequence, loads each word with acquire, re-reads the sequence and retries when it was odd or
/// changed (a torn read), as wallar::Seqlock (core/seqlock.hpp) does within the process.
///
/// Threading: pure functions and plain values; SharedPoseWriter: one writer thread;
/// read_shared_pose(): any number of threads and processes, concurrently with the writer.
#pragma once

#include <sys/socket.h>

#include <array>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace wallar::client_wire {

inline constexpr std::uint32_t kProtocolVersion = 1;
inline constexpr std::uint32_t kHelloMagic = 0x524c4157;  // "WALR" little-endian
inline constexpr std::size_t kHeaderBytes = 8;
inline constexpr std::uint32_t kMaxClientBody = 256;        //!< a hello and its name
inline constexpr std::uint32_t kMaxServerBody = 16u << 20;  //!< a client refuses more
inline constexpr std::size_t kMaxNameBytes = 64;

enum class MsgType : std::uint16_t {
  kHello = 1,        //!< client: u32 magic, u32 version, name (rest of the body)
  kAccepted = 0x81,  //!< server: u32 version, u32 shm bytes, text; the memfd rides along
  kRefused = 0x82,   //!< server: u32 version, text; then the server closes
  kPlanes = 0x83,    //!< server: a batch of plane changes (one wall model), see PlaneBatch
  kTracking = 0x84,  //!< server: i64 t_ns, u8 state (tracking state changed)
};

/// kPlanes flags: the batch is the whole set (planes absent from it are gone).
inline constexpr std::uint16_t kPlanesFull = 1;

enum class PlaneChange : std::uint8_t { kAdded = 1, kUpdated = 2, kRemoved = 3 };
enum class Orientation : std::uint8_t {
  kHorizontalUpward = 0,
  kHorizontalDownward = 1,
  kVertical = 2,
  kArbitrary = 3
};
enum class Semantic : std::uint8_t { kUnknown = 0, kFloor = 1, kWall = 2, kCeiling = 3 };
enum class Tracking : std::uint8_t { kNone = 0, kInitialising = 1, kTracking = 2, kLost = 3 };

/// A plane as the API gives it (OpenXR's semantics): the plane frame's origin at the centre of
/// the polygon's bounding box, +z along the normal toward the viewer, x and y in the plane;
/// the polygon counter-clockwise seen from +z, in plane coordinates (metres).
struct PlaneRecord {
  PlaneChange change = PlaneChange::kAdded;
  Semantic semantic = Semantic::kUnknown;
  Orientation orientation = Orientation::kArbitrary;
  std::uint32_t id = 0;
  std::uint32_t subsumed_by = 0;   //!< removed: the plane that absorbed it (0: none)
  std::uint64_t change_count = 0;  //!< +1 whenever its geometry changes
  double p_world_plane_m[3] = {0, 0, 0};
  double q_world_plane_xyzw[4] = {0, 0, 0, 1};
  double extent_m[2] = {0, 0};  //!< width along x, height along y
  std::vector<std::array<double, 2>> polygon_m;
};

struct PlaneBatch {
  std::uint16_t flags = 0;
  std::uint64_t model_version = 0;
  std::int64_t t_ns = 0;  //!< the map's time the model was estimated from
  std::vector<PlaneRecord> planes;
};

// ---- encoding -----------------------------------------------------------------------------

namespace detail {
template <typename T>
void put(std::vector<std::uint8_t>& out, T v) {
  static_assert(std::is_trivially_copyable_v<T>);
  const std::size_t at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &v, sizeof(T));  // little-endian hosts only (static_assert below)
}
static_assert(std::endian::native == std::endian::little, "the wire is little-endian");

/// Reads from a body; every get checks the bounds, `ok` turns false at the first short read.
struct Reader {
  const std::uint8_t* p;
  std::size_t n;
  std::size_t at = 0;
  bool ok = true;
  template <typename T>
  T get() {
    T v{};
    if (!ok || n - at < sizeof(T)) {
      ok = false;
      return v;
    }
    std::memcpy(&v, p + at, sizeof(T));
    at += sizeof(T);
    return v;
  }
};
}  // namespace detail

/// Starts a message: its header with the body's length left 0 (finish() sets it).
inline void begin(std::vector<std::uint8_t>& out, MsgType type, std::uint16_t flags = 0) {
  out.clear();
  detail::put<std::uint32_t>(out, 0);
  detail::put<std::uint16_t>(out, static_cast<std::uint16_t>(type));
  detail::put<std::uint16_t>(out, flags);
}
inline void finish(std::vector<std::uint8_t>& out) {
  const auto body = static_cast<std::uint32_t>(out.size() - kHeaderBytes);
  std::memcpy(out.data(), &body, sizeof body);
}

struct Header {
  std::uint32_t body_bytes = 0;
  MsgType type{};
  std::uint16_t flags = 0;
};
inline Header parse_header(const std::uint8_t* p) {
  Header h;
  std::uint16_t t = 0;
  std::memcpy(&h.body_bytes, p, 4);
  std::memcpy(&t, p + 4, 2);
  std::memcpy(&h.flags, p + 6, 2);
  h.type = static_cast<MsgType>(t);
  return h;
}

inline std::vector<std::uint8_t> encode_hello(std::uint32_t version, std::string_view name,
                                              std::uint32_t magic = kHelloMagic) {
  std::vector<std::uint8_t> out;
  begin(out, MsgType::kHello);
  detail::put(out, magic);
  detail::put(out, version);
  name = name.substr(0, kMaxNameBytes);
  out.insert(out.end(), name.begin(), name.end());
  finish(out);
  return out;
}

/// A client's hello, parsed; or why it is malformed (`error` non-empty).
struct Hello {
  std::uint32_t version = 0;
  std::string name;
  std::string error;
};
inline Hello parse_hello(const std::uint8_t* body, std::size_t n) {
  Hello h;
  detail::Reader r{body, n};
  const auto magic = r.get<std::uint32_t>();
  h.version = r.get<std::uint32_t>();
  if (!r.ok) {
    h.error = "a hello of " + std::to_string(n) + " bytes (at least 8)";
  } else if (magic != kHelloMagic) {
    h.error = "a hello without the magic (not a wallar client)";
  } else if (n - r.at > kMaxNameBytes) {
    h.error = "a client name over " + std::to_string(kMaxNameBytes) + " bytes";
  } else {
    h.name.assign(reinterpret_cast<const char*>(body + r.at), n - r.at);
    for (char& c : h.name) {
      if (c < 0x20 || c > 0x7e) c = '?';  // printed in the log
    }
  }
  return h;
}

/// kAccepted or kRefused: u32 version, then the text.
inline std::vector<std::uint8_t> encode_answer(MsgType type, std::uint32_t a, std::uint32_t b,
                                               std::string_view text) {
  std::vector<std::uint8_t> out;
  begin(out, type);
  detail::put(out, a);
  if (type == MsgType::kAccepted) detail::put(out, b);
  out.insert(out.end(), text.begin(), text.end());
  finish(out);
  return out;
}

inline void encode_tracking(std::vector<std::uint8_t>& out, std::int64_t t_ns, Tracking state) {
  begin(out, MsgType::kTracking);
  detail::put(out, t_ns);
  detail::put(out, static_cast<std::uint8_t>(state));
  finish(out);
}

inline void encode_planes(std::vector<std::uint8_t>& out, const PlaneBatch& batch) {
  begin(out, MsgType::kPlanes, batch.flags);
  detail::put(out, batch.model_version);
  detail::put(out, batch.t_ns);
  detail::put(out, static_cast<std::uint32_t>(batch.planes.size()));
  for (const PlaneRecord& p : batch.planes) {
    detail::put(out, static_cast<std::uint8_t>(p.change));
    detail::put(out, static_cast<std::uint8_t>(p.semantic));
    detail::put(out, static_cast<std::uint8_t>(p.orientation));
    detail::put(out, std::uint8_t{0});
    detail::put(out, p.id);
    detail::put(out, p.subsumed_by);
    detail::put(out, p.change_count);
    for (double v : p.p_world_plane_m) detail::put(out, v);
    for (double v : p.q_world_plane_xyzw) detail::put(out, v);
    for (double v : p.extent_m) detail::put(out, v);
    detail::put(out, static_cast<std::uint32_t>(p.polygon_m.size()));
    for (const auto& xy : p.polygon_m) {
      detail::put(out, xy[0]);
      detail::put(out, xy[1]);
    }
  }
  finish(out);
}

/// A kPlanes body, parsed; nullopt when it is short, long or out of range.
inline std::optional<PlaneBatch> parse_planes(const std::uint8_t* body, std::size_t n,
                                              std::uint16_t flags) {
  detail::Reader r{body, n};
  PlaneBatch b;
  b.flags = flags;
  b.model_version = r.get<std::uint64_t>();
  b.t_ns = r.get<std::int64_t>();
  const auto count = r.get<std::uint32_t>();
  constexpr std::size_t kPlaneMinBytes = 4 + 4 + 4 + 8 + 9 * 8 + 4;
  if (!r.ok || count > (n - r.at) / kPlaneMinBytes) return std::nullopt;
  b.planes.resize(count);
  for (PlaneRecord& p : b.planes) {
    const auto change = r.get<std::uint8_t>();
    const auto semantic = r.get<std::uint8_t>();
    const auto orientation = r.get<std::uint8_t>();
    (void)r.get<std::uint8_t>();
    if (change < 1 || change > 3 || semantic > 3 || orientation > 3) return std::nullopt;
    p.change = static_cast<PlaneChange>(change);
    p.semantic = static_cast<Semantic>(semantic);
    p.orientation = static_cast<Orientation>(orientation);
    p.id = r.get<std::uint32_t>();
    p.subsumed_by = r.get<std::uint32_t>();
    p.change_count = r.get<std::uint64_t>();
    for (double& v : p.p_world_plane_m) v = r.get<double>();
    for (double& v : p.q_world_plane_xyzw) v = r.get<double>();
    for (double& v : p.extent_m) v = r.get<double>();
    const auto vertices = r.get<std::uint32_t>();
    if (!r.ok || vertices > (n - r.at) / 16) return std::nullopt;
    p.polygon_m.resize(vertices);
    for (auto& xy : p.polygon_m) {
      xy[0] = r.get<double>();
      xy[1] = r.get<double>();
    }
  }
  if (!r.ok || r.at != n) return std::nullopt;
  return b;
}

/// One message with room for one file descriptor (SCM_RIGHTS): the accepted answer, which
/// carries the memfd, for sendmsg() and recvmsg().
struct FdMessage {
  iovec iov{};
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))] = {};
  msghdr header{};
  FdMessage(void* data, std::size_t bytes) : iov{data, bytes} {
    header.msg_iov = &iov;
    header.msg_iovlen = 1;
    header.msg_control = control;
    header.msg_controllen = sizeof control;
  }
  FdMessage(const FdMessage&) = delete;
  FdMessage& operator=(const FdMessage&) = delete;
};

// ---- shared pose --------------------------------------------------------------------------

/// The newest pose and what a reader needs to predict it (plain data, copied by the seqlock).
/// Frames: world = the first body pose's (as the run's files), body = the IMU's.
struct PosePayload {
  std::int64_t t_pose_ns = 0;  //!< the tracked pose's time (sensor clock)
  double q_world_body_xyzw[4] = {0, 0, 0, 1};
  double p_world_body_m[3] = {0, 0, 0};
  double v_world_body_m_s[3] = {0, 0, 0};  //!< from the last tracked poses
  /// The rotation integrated from the bias-corrected gyro since t_pose_ns (body at t_pose ->
  /// body at t_imu_ns), and the newest bias-corrected angular rate (body frame).
  std::int64_t t_imu_ns = 0;
  double q_pose_imu_xyzw[4] = {0, 0, 0, 1};
  double omega_body_rad_s[3] = {0, 0, 0};
  std::int64_t sensor_minus_monotonic_ns = 0;  //!< sensor clock - CLOCK_MONOTONIC
  std::uint64_t updates = 0;                   //!< stores so far
  std::uint32_t epoch = 0;                     //!< +1 per reset
  std::uint8_t tracking = 0;                   //!< Tracking
  std::uint8_t has_pose = 0;
  std::uint8_t has_imu = 0;
  std::uint8_t pad = 0;
  /// The view an app renders from: the headset's rectified left camera (the video see-through
  /// eye) in the body frame, T_body_view (constant for a run; x right, y down, z forward).
  double q_body_view_xyzw[4] = {0, 0, 0, 1};
  double p_body_view_m[3] = {0, 0, 0};
};
static_assert(std::is_trivially_copyable_v<PosePayload>);

inline constexpr std::uint64_t kShmMagic = 0x45534f5052414c57ull;  // "WALRPOSE" little-endian
inline constexpr std::uint64_t kShmLayout = 2;  //!< 2: PosePayload carries T_body_view
inline constexpr std::size_t kPayloadWords = (sizeof(PosePayload) + 7) / 8;
inline constexpr std::size_t kCacheLine = 64;

/// The memfd's content. Only ever accessed through atomic_ref (never as plain members).
struct SharedPoseBlock {
  alignas(kCacheLine) std::uint64_t magic;
  std::uint64_t layout;
  std::uint64_t payload_words;
  alignas(kCacheLine) std::uint64_t seq;
  std::uint64_t words[kPayloadWords];
};
inline constexpr std::size_t kShmBytes = 4096;
static_assert(sizeof(SharedPoseBlock) <= kShmBytes);
static_assert(std::atomic_ref<std::uint64_t>::is_always_lock_free,
              "the shared pose needs lock-free 64-bit atomics (valid across processes)");

using Word = std::atomic_ref<std::uint64_t>;

/// The writer's side over a mapped block. One writer thread; never waits, never allocates.
class SharedPoseWriter {
 public:
  explicit SharedPoseWriter(SharedPoseBlock* block = nullptr) : block_(block) {
    if (block_ == nullptr) return;
    Word(block_->seq).store(0, std::memory_order_relaxed);
    store(PosePayload{});
    Word(block_->payload_words).store(kPayloadWords, std::memory_order_relaxed);
    Word(block_->layout).store(kShmLayout, std::memory_order_relaxed);
    Word(block_->magic).store(kShmMagic, std::memory_order_release);
  }
  [[nodiscard]] bool attached() const { return block_ != nullptr; }

  void store(const PosePayload& value) noexcept {
    std::uint64_t buf[kPayloadWords] = {};
    std::memcpy(buf, &value, sizeof value);
    Word seq(block_->seq);
    const std::uint64_t s = seq.load(std::memory_order_relaxed);
    seq.store(s + 1, std::memory_order_relaxed);  // odd: a store is in progress
    for (std::size_t i = 0; i < kPayloadWords; ++i)
      Word(block_->words[i]).store(buf[i], std::memory_order_release);
    seq.store(s + 2, std::memory_order_release);
  }

 private:
  SharedPoseBlock* block_;
};

/// One attempt to read; false on a torn read (a store in progress or done meanwhile).
inline bool try_read_shared_pose(const SharedPoseBlock* block, PosePayload& out) noexcept {
  auto* b = const_cast<SharedPoseBlock*>(block);  // atomic_ref needs non-const; loads only
  Word seq(b->seq);
  const std::uint64_t before = seq.load(std::memory_order_acquire);
  if ((before & 1U) != 0) return false;
  std::uint64_t buf[kPayloadWords];
  for (std::size_t i = 0; i < kPayloadWords; ++i)
    buf[i] = Word(b->words[i]).load(std::memory_order_acquire);
  if (seq.load(std::memory_order_relaxed) != before) return false;
  std::memcpy(static_cast<void*>(&out), buf, sizeof out);
  return true;
}

/// Whether a mapped block is one this reader understands.
inline bool shared_pose_valid(const SharedPoseBlock* block) noexcept {
  auto* b = const_cast<SharedPoseBlock*>(block);
  return Word(b->magic).load(std::memory_order_acquire) == kShmMagic &&
         Word(b->layout).load(std::memory_order_relaxed) == kShmLayout &&
         Word(b->payload_words).load(std::memory_order_relaxed) == kPayloadWords;
}

}  // namespace wallar::client_wire
