// SPDX-License-Identifier: Apache-2.0
/// @file wallar_client.hpp
/// @brief A header-only C++ wrapper over libwallar-client's C API (wallar_client.h): RAII
/// handles, exceptions for connection errors, std::vector for events and polygons.
///
/// Threading: as the C API's. A wallar::Client is used by one thread at a time, except
/// locate() and now_ns(), which any thread may call at any time; a Planes snapshot is
/// immutable and may be read from any thread.
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "wallar_client.h"

namespace wallar {

/// A snapshot of every plane (wallar_client_begin_planes ... wallar_planes_end).
class Planes {
 public:
  explicit Planes(wallar_planes* p) : p_(p) {}
  Planes(Planes&& o) noexcept : p_(std::exchange(o.p_, nullptr)) {}
  Planes& operator=(Planes&& o) noexcept {
    std::swap(p_, o.p_);
    return *this;
  }
  Planes(const Planes&) = delete;
  Planes& operator=(const Planes&) = delete;
  ~Planes() { wallar_planes_end(p_); }

  [[nodiscard]] std::size_t size() const { return wallar_planes_count(p_); }
  [[nodiscard]] std::uint64_t model_version() const { return wallar_planes_model_version(p_); }
  [[nodiscard]] wallar_plane operator[](std::size_t i) const {
    wallar_plane out{};
    if (wallar_planes_get(p_, i, &out) != 0) throw std::out_of_range("wallar::Planes index");
    return out;
  }
  /// Plane i's polygon in its plane frame (x, y in metres), counter-clockwise.
  [[nodiscard]] std::vector<std::array<double, 2>> polygon(std::size_t i) const {
    std::vector<std::array<double, 2>> xy(wallar_planes_polygon(p_, i, nullptr, 0));
    wallar_planes_polygon(p_, i, xy.empty() ? nullptr : xy[0].data(), xy.size());
    return xy;
  }

 private:
  wallar_planes* p_;
};

class Client {
 public:
  /// Connects; throws std::runtime_error with the one-line reason (the firmware's message
  /// on a version mismatch or a refusal).
  explicit Client(const std::string& path, const std::string& app_name = "") {
    char error[512] = {};
    if (wallar_client_connect(path.c_str(), app_name.c_str(), &c_, error, sizeof error) != 0)
      throw std::runtime_error(error);
  }
  Client(Client&& o) noexcept : c_(std::exchange(o.c_, nullptr)) {}
  Client& operator=(Client&& o) noexcept {
    std::swap(c_, o.c_);
    return *this;
  }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;
  ~Client() { wallar_client_disconnect(c_); }

  [[nodiscard]] int fd() const { return wallar_client_fd(c_); }
  [[nodiscard]] std::int64_t now_ns() const { return wallar_client_now_ns(c_); }
  /// The pose predicted at t_ns (flags say what is valid).
  [[nodiscard]] wallar_pose locate(std::int64_t t_ns) const {
    wallar_pose p{};
    if (wallar_client_locate(c_, t_ns, &p) != 0)
      throw std::runtime_error("wallar: the shared pose gave no consistent read");
    return p;
  }
  /// The view apps render from in the body frame: {q_body_view_xyzw[4], p_body_view_m[3]}.
  [[nodiscard]] std::array<double, 7> view() const {
    std::array<double, 7> v{};
    if (wallar_client_view(c_, v.data(), v.data() + 4) != 0)
      throw std::runtime_error("wallar: the shared pose gave no consistent read");
    return v;
  }
  /// Events that arrived, waiting up to timeout_ms for the first; empty with `closed` set
  /// once the firmware is gone (after one WALLAR_EVENT_DISCONNECTED).
  std::vector<wallar_event> poll(int timeout_ms, bool* closed = nullptr) {
    std::vector<wallar_event> out(64);
    const int n =
        wallar_client_poll_events(c_, timeout_ms, out.data(), static_cast<int>(out.size()));
    if (closed != nullptr) *closed = n < 0;
    out.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
    return out;
  }
  [[nodiscard]] Planes planes() {
    wallar_planes* p = nullptr;
    if (wallar_client_begin_planes(c_, &p) != 0) throw std::bad_alloc();
    return Planes(p);
  }
  [[nodiscard]] wallar_client* handle() const { return c_; }

 private:
  wallar_client* c_ = nullptr;
};

}  // namespace wallar
