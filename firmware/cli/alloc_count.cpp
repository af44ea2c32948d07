// SPDX-License-Identifier: Apache-2.0
/// @file alloc_count.cpp
/// @brief The wallar executable's operator new counts each allocation into the calling
/// thread's counter when the appliance has set one (its module threads after start-up), so
/// `wallar run --stats` shows allocations per fixed-rate thread on the device itself.
///
/// One thread-local load and a branch per allocation. Sanitizer builds keep their own
/// operator new (its checks matter more there), and their stats show "-".
#include <atomic>
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

void* operator new(std::size_t size) {
  count_allocation();
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t al) {
  count_allocation();
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
