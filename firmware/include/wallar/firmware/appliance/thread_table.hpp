// SPDX-License-Identifier: Apache-2.0
/// @file thread_table.hpp
/// @brief The thread table: every thread the appliance starts, in one place (name, SCHED_FIFO
/// priority, CPU, stack, role). Priorities apply only when the appliance runs in real time and
/// the system permits SCHED_FIFO (else SCHED_OTHER, said once per thread). A board file's
/// `threads:` section overrides a thread's policy (fifo, rr, other), priority and CPU
/// (board/rpi5.yaml keeps tracking off the CPU that takes the USB interrupts).
///
/// Threading: constant data and pure functions; any thread.
#pragma once

#include <cstddef>
#include <span>

#include "wallar/firmware/board.hpp"
#include "wallar/firmware/rt_thread.hpp"

namespace wallar::firmware {

struct ThreadTableEntry {
  const char* name;
  int priority;  //!< SCHED_FIFO priority in real time; 0: SCHED_OTHER
  int cpu;       //!< -1: any
  std::size_t stack_bytes;
  const char* role;
  bool round_robin;  //!< with priority > 0: SCHED_RR instead of SCHED_FIFO (a board's policy)
};

/// The table, in start order of the sensor side first.
std::span<const ThreadTableEntry> thread_table();
/// The entry named `name`, with the board's overrides when given; throws std::logic_error for
/// a name the table lacks.
ThreadTableEntry thread_table_entry(const char* name, const BoardConfig* board = nullptr);
/// The placement of thread `name` (the board's when given): its priority when `realtime`,
/// SCHED_OTHER otherwise.
ThreadSpec thread_spec(const char* name, bool realtime, const BoardConfig* board = nullptr);

}  // namespace wallar::firmware
