// SPDX-License-Identifier: Apache-2.0
/// @file v4l2_system.hpp
/// @brief The thin system-call seam under the V4L2 driver: open/close/ioctl/mmap/munmap/poll
/// and the monotonic clock, with libc's conventions (-1 and errno on failure).
///
/// The product uses LinuxV4l2System (the real calls). Tests put a fake device behind the same
/// seam (tests/unit/fake_v4l2): it receives exactly the ioctl structures the kernel would, so
/// the driver's code path is the same except for this class.
///
/// Threading: LinuxV4l2System is stateless and thread-safe. A fake documents its own contract.
#pragma once

#include <poll.h>
#include <sys/types.h>

#include <cstddef>

#include "wallar/core/time.hpp"

namespace wallar::drivers {

class V4l2System {
 public:
  virtual ~V4l2System() = default;
  virtual int open(const char* path, int flags) = 0;
  virtual int close(int fd) = 0;
  /// `request` is a VIDIOC_* code; `arg` points at its structure.
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;  // NOLINT(google-runtime-int)
  virtual void* mmap(std::size_t length, int prot, int flags, int fd, off_t offset) = 0;
  virtual int munmap(void* addr, std::size_t length) = 0;
  virtual int poll(pollfd* fds, nfds_t count, int timeout_ms) = 0;
  /// CLOCK_MONOTONIC [ns]: the clock V4L2 stamps buffers with.
  virtual TimeNs now_ns() = 0;
};

/// The real calls (::open, ::ioctl, ...).
class LinuxV4l2System final : public V4l2System {
 public:
  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;  // NOLINT(google-runtime-int)
  void* mmap(std::size_t length, int prot, int flags, int fd, off_t offset) override;
  int munmap(void* addr, std::size_t length) override;
  int poll(pollfd* fds, nfds_t count, int timeout_ms) override;
  TimeNs now_ns() override;
};

/// The process's one LinuxV4l2System. It is never destroyed: a camera's frames can outlive the
/// camera (a consumer still holds one while the capture side is torn down), and the last one
/// released unmaps its kernel buffer through the system that mapped it, so that system must
/// outlive every frame. A fake in a test must likewise outlive the frames it mapped.
V4l2System& linux_v4l2_system();

}  // namespace wallar::drivers
