// SPDX-License-Identifier: Apache-2.0
/// @file allocation_count.cpp
/// @brief The per-thread allocation counter's storage (the counting operator new lives in the
/// executable that replaces it: firmware/cli/alloc_count.cpp).
#include "wallar/firmware/appliance/allocation_count.hpp"

namespace wallar::firmware {

thread_local std::atomic<std::uint64_t>* tl_allocation_counter = nullptr;
bool g_allocations_counted = false;

}  // namespace wallar::firmware
