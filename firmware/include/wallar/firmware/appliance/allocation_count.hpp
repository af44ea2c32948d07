// SPDX-License-Identifier: Apache-2.0
/// @file allocation_count.hpp
/// @brief Heap allocations counted per thread: a build that replaces operator new (the wallar
/// executable, the allocation tests) counts into the calling thread's counter when one is set.
/// The appliance sets one for its fixed-rate threads once their start-up is over.
///
/// Threading: the pointer is thread-local (each thread sets its own); the counters it points
/// to are atomics read by the supervisor.
#pragma once

#include <atomic>
#include <cstdint>

namespace wallar::firmware {

extern thread_local std::atomic<std::uint64_t>* tl_allocation_counter;
/// True in builds whose operator new counts (set by the replacement's translation unit).
extern bool g_allocations_counted;

/// Pauses the calling thread's counting for a scope: the rare logged event or a reset, which
/// may allocate, on a thread whose fixed-rate path must not.
class AllocationPause {
 public:
  AllocationPause() : saved_(tl_allocation_counter) { tl_allocation_counter = nullptr; }
  ~AllocationPause() { tl_allocation_counter = saved_; }
  AllocationPause(const AllocationPause&) = delete;
  AllocationPause& operator=(const AllocationPause&) = delete;

 private:
  std::atomic<std::uint64_t>* saved_;
};

}  // namespace wallar::firmware
