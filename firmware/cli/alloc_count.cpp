// SPDX-License-Identifier: Apache-2.0
/// @file alloc_count.cpp
/// @brief The wallar executable counts each heap allocation into the calling thread's counter
/// when the appliance has set one (its module threads after start-up), so `wallar run --stats`
/// shows allocations per fixed-rate thread on the device itself.
///
/// The C allocator is counted (malloc, calloc, realloc, aligned_alloc, memalign,
/// posix_memalign), not only operator new, which allocates through it: Eigen's dynamic
/// matrices and OpenCV's images (fastMalloc: posix_memalign) call it directly and were not
/// seen. The executable's definitions take precedence over glibc's for every library; glibc's
/// own entry points (__libc_*) do the work, and free() stays glibc's. One thread-local load
/// and a branch per allocation; the counter pointer lives in the executable's static TLS, so
/// reading it never allocates. Sanitizer builds keep their interceptors, and their stats show
/// "-".
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <new>

#include "wallar/firmware/appliance/allocation_count.hpp"

#if !defined(WALLAR_SANITIZED)

namespace {
const bool kRegistered = (wallar::firmware::g_allocations_counted = true);

inline void count_allocation() {
  if (std::atomic<std::uint64_t>* c = wallar::firmware::tl_allocation_counter) {
    c->fetch_add(1, std::memory_order_relaxed);
  }
}
}  // namespace

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);

void* malloc(std::size_t size) noexcept {
  count_allocation();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  count_allocation();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) noexcept {
  count_allocation();
  return __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  count_allocation();
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  count_allocation();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  count_allocation();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
}

// operator new allocates through malloc above, which counts it.
void* operator new(std::size_t size) {
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t al) {
  const auto a = static_cast<std::size_t>(al);
  if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t al) { return operator new(size, al); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

#endif
