// SPDX-License-Identifier: Apache-2.0
/// @file v4l2_system.cpp
/// @brief The real system calls behind the V4L2 seam.
#include "wallar/drivers/camera/v4l2_system.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <ctime>

namespace wallar::drivers {

V4l2System& linux_v4l2_system() {
  static auto* const sys = new LinuxV4l2System();  // NOLINT: never destroyed (see the header)
  return *sys;
}

int LinuxV4l2System::open(const char* path, int flags) { return ::open(path, flags); }
int LinuxV4l2System::close(int fd) { return ::close(fd); }
int LinuxV4l2System::ioctl(int fd, unsigned long request, void* arg) {  // NOLINT
  return ::ioctl(fd, request, arg);
}
void* LinuxV4l2System::mmap(std::size_t length, int prot, int flags, int fd, off_t offset) {
  return ::mmap(nullptr, length, prot, flags, fd, offset);
}
int LinuxV4l2System::munmap(void* addr, std::size_t length) { return ::munmap(addr, length); }
int LinuxV4l2System::poll(pollfd* fds, nfds_t count, int timeout_ms) {
  return ::poll(fds, count, timeout_ms);
}
TimeNs LinuxV4l2System::now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<TimeNs>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

}  // namespace wallar::drivers
