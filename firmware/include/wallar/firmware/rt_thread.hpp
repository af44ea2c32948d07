// SPDX-License-Identifier: Apache-2.0
/// @file rt_thread.hpp
/// @brief Threads with a real-time placement (SCHED_FIFO priority, CPU pin, stack size) that
/// degrade gracefully where the placement is not permitted, and memory locking.
///
/// An RtThread asks for its ThreadSpec through pthread attributes. When the system refuses the
/// real-time policy (no CAP_SYS_NICE, RLIMIT_RTPRIO 0: EPERM; or EINVAL) it runs with ordinary
/// scheduling instead, and when the CPU is not online or not in the process's CPU mask it runs
/// unpinned; placement() says what the thread actually got, and `fallback` says why in one line,
/// for the log. Other failures (EAGAIN: too many threads) throw. The constructor returns once
/// the thread runs (named, its CPU clock known), before its body starts. An exception escaping
/// the body is caught and kept (failed(), error()) rather than terminating the process.
///
/// Threading: the owning thread constructs, moves, join()s and destroys an RtThread and reads
/// spec(), placement(), native_handle(); cpu_time_ns(), finished(), failed() and error() may be
/// called from any thread while the object is alive (not concurrently with a move or with
/// destruction). lock_memory() is a plain function, best called once at start-up before the
/// fixed-rate threads start. ScopedThreadPriority changes the calling thread only.
#pragma once

#include <pthread.h>

#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <string>

namespace wallar::firmware {

/// What a thread asks for.
struct ThreadSpec {
  std::string name;             //!< thread name (pthread_setname_np keeps the first 15 chars)
  int priority = 0;             //!< 0: SCHED_OTHER; 1..99: SCHED_FIFO at that priority
  int cpu = -1;                 //!< pin to this CPU; -1: any CPU
  std::size_t stack_bytes = 0;  //!< 0: the default stack size (else rounded up to pages)
  /// With priority > 0: SCHED_RR (time slices among threads of equal priority) instead of
  /// SCHED_FIFO.
  bool round_robin = false;
};

/// What a thread got.
struct ThreadPlacement {
  bool fifo = false;            //!< runs a real-time policy (SCHED_FIFO, or SCHED_RR)
  bool round_robin = false;     //!< that policy is SCHED_RR
  int priority = 0;             //!< its real-time priority (0 when not SCHED_FIFO)
  int cpu = -1;                 //!< the CPU it is pinned to; -1: not pinned by us
  std::size_t stack_bytes = 0;  //!< its stack size
  /// Empty, or one line saying why the spec could not be applied, e.g.
  /// "SCHED_FIFO 80 not permitted (EPERM): running SCHED_OTHER".
  std::string fallback;
};

class RtThread {
 public:
  /// Starts `body` on a new thread placed per `spec`; returns once the thread runs. Throws
  /// std::invalid_argument for an empty body or a priority outside 0..99, std::system_error
  /// (naming the thread) when the thread cannot be created even with default placement.
  RtThread(ThreadSpec spec, std::function<void()> body);
  ~RtThread();  //!< joins if joinable
  RtThread(RtThread&& other) noexcept;
  RtThread& operator=(RtThread&& other) noexcept;  //!< joins this thread first if joinable
  RtThread(const RtThread&) = delete;
  RtThread& operator=(const RtThread&) = delete;

  /// Waits for the body to return. Throws std::system_error when not joinable.
  void join();
  [[nodiscard]] bool joinable() const { return state_ != nullptr && !joined_; }

  [[nodiscard]] const ThreadSpec& spec() const { return spec_; }
  [[nodiscard]] const ThreadPlacement& placement() const { return placement_; }
  [[nodiscard]] pthread_t native_handle() const { return handle_; }

  /// CPU time the thread has used: live while it runs, its final figure once the body has
  /// returned (also after join()). 0 for a moved-from object.
  [[nodiscard]] std::int64_t cpu_time_ns() const;
  /// True once the body has returned (normally or by an exception).
  [[nodiscard]] bool finished() const;
  /// True when an exception escaped the body.
  [[nodiscard]] bool failed() const;
  /// The escaped exception's what() ("unknown exception" for non-std ones); empty otherwise.
  [[nodiscard]] std::string error() const;
  /// The escaped exception itself (to rethrow with its type), null otherwise.
  [[nodiscard]] std::exception_ptr exception() const;

 private:
  struct State;
  static void* entry(void* arg);
  void start();

  ThreadSpec spec_;
  ThreadPlacement placement_;
  std::unique_ptr<State> state_;  // shared with the thread; outlives it (freed after join)
  pthread_t handle_{};
  bool joined_ = false;
};

/// The calling thread at SCHED_FIFO (SCHED_RR with `round_robin`) `priority` while the object
/// lives (0: left as it is), its
/// previous policy and priority back when it goes. Where the policy is refused the thread keeps
/// its own, and placement().fallback says why in one line (as RtThread's). For a loop on a
/// thread RtThread did not create: the appliance's supervisor on the main thread.
/// Threading: constructed and destroyed on the thread it changes.
class ScopedThreadPriority {
 public:
  explicit ScopedThreadPriority(int priority, bool round_robin = false);
  ~ScopedThreadPriority();
  ScopedThreadPriority(const ScopedThreadPriority&) = delete;
  ScopedThreadPriority& operator=(const ScopedThreadPriority&) = delete;

  [[nodiscard]] const ThreadPlacement& placement() const { return placement_; }

 private:
  ThreadPlacement placement_;
  int old_policy_ = 0;
  int old_priority_ = 0;
  bool changed_ = false;
};

struct MemoryLock {
  bool locked = false;
  std::string warning;  //!< empty when locked, else one line for the log
};

/// mlockall(MCL_CURRENT | MCL_FUTURE), so the fixed-rate threads never wait for a page fault.
/// On failure returns a one-line warning naming errno, e.g. "mlockall: Operation not permitted
/// (EPERM; needs CAP_IPC_LOCK or a higher RLIMIT_MEMLOCK): pages may fault in the fixed-rate
/// threads". With MCL_FUTURE every thread created afterwards has its whole stack locked (8 MiB
/// by default): give threads started after it a ThreadSpec::stack_bytes.
MemoryLock lock_memory();

}  // namespace wallar::firmware
