// SPDX-License-Identifier: Apache-2.0
/// @file stats.hpp
/// @brief The stats table of the appliance (threads, then stages) and the process's resident
/// memory, as the supervisor samples it.
///
/// Threading: row_of()/stage_row() read their arguments' atomics and may run while the
/// threads do; current_rss_kb() allocates nothing (the supervisor's tick); all from any thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "wallar/firmware/appliance/records.hpp"
#include "wallar/firmware/latency_histogram.hpp"
#include "wallar/firmware/rt_thread.hpp"

namespace wallar::firmware {

/// A thread's row: its placement, CPU time and share of `run_ns`, and the given counters
/// (`allocations` may be null: not counted).
ThreadRow row_of(const RtThread& t, DurationNs run_ns, std::uint64_t wakeups, std::uint64_t misses,
                 const std::atomic<std::uint64_t>* allocations);
StageRow stage_row(const char* name, const LatencyHistogram& h, DurationNs deadline_ns,
                   std::uint64_t misses);
/// The rows as `wallar run --json` and the live server's stats channel write them.
nlohmann::json to_json(const std::vector<ThreadRow>& threads);
nlohmann::json to_json(const std::vector<StageRow>& stages);
/// The stats table (threads, then stages), fixed-width text.
std::string format_stats_table(const std::vector<ThreadRow>& threads,
                               const std::vector<StageRow>& stages);

/// Resident memory now [KiB], read from /proc without allocating; 0 when unreadable.
long current_rss_kb();
/// The peak resident memory of the process [KiB].
long max_rss_kb();

}  // namespace wallar::firmware
