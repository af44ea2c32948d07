// SPDX-License-Identifier: Apache-2.0
/// @file stats.cpp
/// @brief Rows of the stats table, its text, and resident memory.
#include "wallar/firmware/appliance/stats.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>

#include "wallar/firmware/appliance/allocation_count.hpp"
#include "wallar/firmware/appliance/thread_table.hpp"

namespace wallar::firmware {
namespace {

std::string policy_of(const RtThread& t) {
  const ThreadPlacement& p = t.placement();
  return p.fifo ? (p.round_robin ? "RR " : "FIFO ") + std::to_string(p.priority)
                : std::string("OTHER");
}

}  // namespace

ThreadRow row_of(const RtThread& t, DurationNs run_ns, std::uint64_t wakeups, std::uint64_t misses,
                 const std::atomic<std::uint64_t>* allocations) {
  ThreadRow r;
  r.name = t.spec().name;
  r.policy = policy_of(t);
  r.cpu = t.placement().cpu;
  r.cpu_s = ns_to_s(t.cpu_time_ns());
  r.cpu_percent =
      run_ns > 0 ? 100.0 * static_cast<double>(t.cpu_time_ns()) / static_cast<double>(run_ns) : 0.0;
  r.wakeups = wakeups;
  r.misses = misses;
  if (allocations != nullptr && g_allocations_counted) r.allocations = allocations->load();
  r.note = t.placement().fallback.empty() ? thread_table_entry(t.spec().name.c_str()).role
                                          : t.placement().fallback;
  return r;
}

StageRow stage_row(const char* name, const LatencyHistogram& h, DurationNs deadline_ns,
                   std::uint64_t misses) {
  StageRow s;
  s.name = name;
  s.latency = h.summary();
  s.deadline_ns = deadline_ns;
  s.misses = misses;
  return s;
}

nlohmann::json to_json(const std::vector<ThreadRow>& threads) {
  nlohmann::json rows = nlohmann::json::array();
  for (const ThreadRow& t : threads) {
    rows.push_back({{"name", t.name},
                    {"policy", t.policy},
                    {"cpu", t.cpu},
                    {"cpu_s", t.cpu_s},
                    {"cpu_percent", t.cpu_percent},
                    {"wakeups", t.wakeups},
                    {"misses", t.misses},
                    {"allocations_after_start",
                     t.allocations ? nlohmann::json(*t.allocations) : nlohmann::json()},
                    {"note", t.note}});
  }
  return rows;
}

nlohmann::json to_json(const std::vector<StageRow>& stages) {
  nlohmann::json rows = nlohmann::json::array();
  for (const StageRow& s : stages) {
    const LatencySummary& l = s.latency;
    rows.push_back({{"name", s.name},
                    {"count", l.count},
                    {"p50_ms", l.p50_ms},
                    {"p99_ms", l.p99_ms},
                    {"max_ms", l.max_ms},
                    {"mean_ms", l.mean_ms},
                    {"deadline_ms", static_cast<double>(s.deadline_ns) * 1e-6},
                    {"misses", s.misses}});
  }
  return rows;
}

std::string format_stats_table(const std::vector<ThreadRow>& threads,
                               const std::vector<StageRow>& stages) {
  std::string out;
  char line[320];
  std::snprintf(line, sizeof line, "%-12s %-9s %4s %9s %6s %9s %7s %7s  %s\n", "thread", "policy",
                "cpu", "cpu_s", "cpu%", "wakeups", "misses", "allocs", "role");
  out += line;
  for (const ThreadRow& t : threads) {
    const std::string allocs = t.allocations ? std::to_string(*t.allocations) : "-";
    std::snprintf(line, sizeof line, "%-12s %-9s %4s %9.3f %6.1f %9llu %7llu %7s  %s\n",
                  t.name.c_str(), t.policy.c_str(),
                  t.cpu < 0 ? "any" : std::to_string(t.cpu).c_str(), t.cpu_s, t.cpu_percent,
                  static_cast<unsigned long long>(t.wakeups),
                  static_cast<unsigned long long>(t.misses), allocs.c_str(), t.note.c_str());
    out += line;
  }
  std::snprintf(line, sizeof line, "\n%-22s %8s %9s %9s %9s %9s %8s %7s\n", "stage", "count",
                "p50_ms", "p99_ms", "max_ms", "mean_ms", "dl_ms", "misses");
  out += line;
  for (const StageRow& s : stages) {
    const std::string deadline =
        s.deadline_ns > 0 ? std::to_string(static_cast<double>(s.deadline_ns) * 1e-6).substr(0, 6)
                          : "-";
    std::snprintf(line, sizeof line, "%-22s %8llu %9.2f %9.2f %9.2f %9.2f %8s %7llu\n",
                  s.name.c_str(), static_cast<unsigned long long>(s.latency.count),
                  s.latency.p50_ms, s.latency.p99_ms, s.latency.max_ms, s.latency.mean_ms,
                  deadline.c_str(), static_cast<unsigned long long>(s.misses));
    out += line;
  }
  return out;
}

long current_rss_kb() {
  const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  char buf[128];
  const ssize_t n = ::read(fd, buf, sizeof buf - 1);
  ::close(fd);
  if (n <= 0) return 0;
  buf[n] = 0;
  long size = 0, resident = 0;
  if (std::sscanf(buf, "%ld %ld", &size, &resident) != 2) return 0;
  return resident * (sysconf(_SC_PAGESIZE) / 1024);
}

long max_rss_kb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

}  // namespace wallar::firmware
