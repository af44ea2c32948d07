// SPDX-License-Identifier: Apache-2.0
/// @file rt_thread.cpp
/// @brief Real-time thread placement with graceful fallback, and memory locking.
#include "wallar/firmware/rt_thread.hpp"

#include <cxxabi.h>
#include <sched.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <climits>
#include <ctime>
#include <exception>
#include <stdexcept>
#include <system_error>
#include <utility>

namespace wallar::firmware {
namespace {

constexpr std::size_t kMaxNameChars = 15;  // pthread names are 16 bytes with the NUL
constexpr int kMaxFifoPriority = 99;

/// How the scheduling policy is set, most wanted first.
enum class Sched { kFifo, kOther, kInherit };

std::string errno_name(int err) {
  switch (err) {
    case EPERM:
      return "EPERM";
    case EINVAL:
      return "EINVAL";
    case ENOMEM:
      return "ENOMEM";
    case EAGAIN:
      return "EAGAIN";
    case ENOSYS:
      return "ENOSYS";
    default:
      return "errno " + std::to_string(err);
  }
}

std::int64_t timespec_to_ns(const timespec& ts) {
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// Owns a pthread_attr_t.
class ThreadAttr {
 public:
  ThreadAttr() {
    const int rc = pthread_attr_init(&attr_);
    if (rc != 0) throw std::system_error(rc, std::generic_category(), "pthread_attr_init");
  }
  ~ThreadAttr() { pthread_attr_destroy(&attr_); }
  ThreadAttr(const ThreadAttr&) = delete;
  ThreadAttr& operator=(const ThreadAttr&) = delete;
  pthread_attr_t* get() { return &attr_; }

 private:
  pthread_attr_t attr_{};
};

/// The scheduling attributes for `sched`; 0 or the pthread_attr_* error.
int set_sched(pthread_attr_t* attr, Sched sched, int priority, bool round_robin) {
  if (sched == Sched::kInherit) return pthread_attr_setinheritsched(attr, PTHREAD_INHERIT_SCHED);
  int rc = pthread_attr_setinheritsched(attr, PTHREAD_EXPLICIT_SCHED);
  if (rc != 0) return rc;
  const int policy = sched != Sched::kFifo ? SCHED_OTHER : round_robin ? SCHED_RR : SCHED_FIFO;
  rc = pthread_attr_setschedpolicy(attr, policy);
  if (rc != 0) return rc;
  sched_param param{};
  param.sched_priority = sched == Sched::kFifo ? priority : 0;
  return pthread_attr_setschedparam(attr, &param);
}

/// The pin for `cpu` (>= 0); 0 or the pthread_attr_setaffinity_np error.
int set_cpu(pthread_attr_t* attr, int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_attr_setaffinity_np(attr, sizeof(set), &set);
}

/// Why `cpu` cannot be used at all (empty when it may be): not online, or beyond cpu_set_t.
std::string unusable_cpu(int cpu) {
  const long online = sysconf(_SC_NPROCESSORS_ONLN);
  if (online > 0 && cpu >= online) {
    return "cpu " + std::to_string(cpu) + " not online (" + std::to_string(online) +
           " online): running on any CPU";
  }
  if (cpu >= CPU_SETSIZE) {
    return "cpu " + std::to_string(cpu) + " beyond CPU_SETSIZE: running on any CPU";
  }
  return {};
}

/// `stack_bytes` raised to the minimum and rounded up to whole pages.
std::size_t round_stack(std::size_t stack_bytes) {
  const long page_l = sysconf(_SC_PAGESIZE);
  const std::size_t page = page_l > 0 ? static_cast<std::size_t>(page_l) : 4096;
  const auto min_bytes = static_cast<std::size_t>(PTHREAD_STACK_MIN);
  const std::size_t bytes = stack_bytes < min_bytes ? min_bytes : stack_bytes;
  return (bytes + page - 1) / page * page;
}

}  // namespace

/// What the owner and the thread share. Allocated by the owner, freed after the join, so it
/// outlives the thread and does not move when the RtThread does.
struct RtThread::State {
  std::function<void()> body;
  std::string name;  // already truncated for pthread_setname_np
  // Written by the thread before `started`:
  bool has_clock = false;
  clockid_t clock{};
  bool fifo = false;  // SCHED_FIFO or SCHED_RR
  bool round_robin = false;
  int priority = 0;
  // Written by the thread before `failed` / `finished`:
  std::string error;
  std::exception_ptr exception;
  std::int64_t final_cpu_ns = 0;

  std::atomic<bool> started{false};
  std::atomic<bool> failed{false};
  std::atomic<bool> finished{false};

  void fail(const char* what, std::exception_ptr e) noexcept {
    exception = std::move(e);
    try {
      error = what;
    } catch (...) {  // no memory for the message: failed() still says so
    }
    failed.store(true, std::memory_order_release);
  }
  void finish() noexcept {
    timespec ts{};
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) == 0) final_cpu_ns = timespec_to_ns(ts);
    finished.store(true, std::memory_order_release);
  }
};

RtThread::RtThread(ThreadSpec spec, std::function<void()> body) : spec_(std::move(spec)) {
  if (!body) throw std::invalid_argument("RtThread '" + spec_.name + "': empty body");
  if (spec_.priority < 0 || spec_.priority > kMaxFifoPriority) {
    throw std::invalid_argument("RtThread '" + spec_.name + "': priority " +
                                std::to_string(spec_.priority) + " outside 0..99");
  }
  state_ = std::make_unique<State>();
  state_->body = std::move(body);
  state_->name = spec_.name.substr(0, kMaxNameChars);
  start();
}

void RtThread::start() {
  std::string fallback;
  const auto note = [&fallback](const std::string& line) {
    if (!fallback.empty()) fallback += "; ";
    fallback += line;
  };

  int cpu = spec_.cpu < 0 ? -1 : spec_.cpu;
  if (cpu >= 0) {
    if (std::string why = unusable_cpu(cpu); !why.empty()) {
      note(why);
      cpu = -1;
    }
  }
  const std::size_t stack_bytes = spec_.stack_bytes > 0 ? round_stack(spec_.stack_bytes) : 0;
  const Sched wanted = spec_.priority > 0 ? Sched::kFifo : Sched::kOther;

  // Most wanted placement first: the policy matters more than the pin, so the pin is dropped
  // before the policy is. EPERM comes from the policy only; EINVAL from either (a CPU outside
  // the cgroup's cpuset, a priority the policy does not take), hence both variants per policy.
  // A failed attempt leaves no thread behind.
  int sched_error = 0;   // first failure of an unpinned attempt: the policy's own errno
  int pinned_error = 0;  // last failure of a pinned attempt
  int last_error = 0;
  bool created = false;
  Sched sched = wanted;
  int pinned = cpu;
  for (int s = static_cast<int>(wanted); !created && s <= static_cast<int>(Sched::kInherit); ++s) {
    sched = static_cast<Sched>(s);
    for (int variant = 0; variant < 2 && !created; ++variant) {
      if (variant == 1 && cpu < 0) break;  // no pin to drop
      const int try_cpu = variant == 0 ? cpu : -1;
      ThreadAttr attr;
      if (stack_bytes > 0) {
        const int rc = pthread_attr_setstacksize(attr.get(), stack_bytes);
        if (rc != 0) {
          throw std::system_error(
              rc, std::generic_category(),
              "RtThread '" + spec_.name + "': stack of " + std::to_string(stack_bytes) + " bytes");
        }
      }
      int rc = set_sched(attr.get(), sched, spec_.priority, spec_.round_robin);
      if (rc == 0 && try_cpu >= 0) rc = set_cpu(attr.get(), try_cpu);
      if (rc == 0) rc = pthread_create(&handle_, attr.get(), &RtThread::entry, state_.get());
      if (rc == 0) {
        std::size_t got = 0;
        if (pthread_attr_getstacksize(attr.get(), &got) == 0) placement_.stack_bytes = got;
        pinned = try_cpu;
        created = true;
        break;
      }
      if (rc != EPERM && rc != EINVAL) {
        throw std::system_error(rc, std::generic_category(),
                                "RtThread '" + spec_.name + "': pthread_create");
      }
      last_error = rc;
      if (try_cpu >= 0) {
        pinned_error = rc;
      } else if (sched_error == 0) {
        sched_error = rc;
      }
    }
  }
  if (!created) {
    throw std::system_error(last_error, std::generic_category(),
                            "RtThread '" + spec_.name + "': pthread_create");
  }

  try {
    if (sched != wanted) {
      if (sched_error == 0) sched_error = pinned_error;
      const std::string asked =
          wanted == Sched::kFifo
              ? (spec_.round_robin ? "SCHED_RR " : "SCHED_FIFO ") + std::to_string(spec_.priority)
              : std::string("SCHED_OTHER");
      const std::string got =
          sched == Sched::kOther ? "running SCHED_OTHER" : "running the inherited policy";
      note(asked + (sched_error == EPERM ? " not permitted (" : " rejected (") +
           errno_name(sched_error) + "): " + got);
    }
    if (pinned != cpu) {
      note("cpu " + std::to_string(cpu) + " rejected (" + errno_name(pinned_error) +
           "): running on any CPU");
    }
  } catch (...) {  // no memory for the note: do not leave the thread running on freed state
    pthread_join(handle_, nullptr);
    throw;
  }

  state_->started.wait(false, std::memory_order_acquire);
  placement_.fifo = state_->fifo;
  placement_.round_robin = state_->round_robin;
  placement_.priority = state_->priority;
  placement_.cpu = pinned;
  placement_.fallback = std::move(fallback);
}

void* RtThread::entry(void* arg) {
  auto* state = static_cast<State*>(arg);
  const pthread_t self = pthread_self();
  if (!state->name.empty()) pthread_setname_np(self, state->name.c_str());
  state->has_clock = pthread_getcpuclockid(self, &state->clock) == 0;
  int policy = SCHED_OTHER;
  sched_param param{};
  if (pthread_getschedparam(self, &policy, &param) == 0) {
    state->fifo = policy == SCHED_FIFO || policy == SCHED_RR;
    state->round_robin = policy == SCHED_RR;
    state->priority = state->fifo ? param.sched_priority : 0;
  }
  state->started.store(true, std::memory_order_release);
  state->started.notify_one();

  try {
    state->body();
  } catch (abi::__forced_unwind&) {  // pthread_exit / cancellation: must propagate
    state->body = nullptr;
    state->finish();
    throw;
  } catch (const std::exception& e) {
    state->fail(e.what(), std::current_exception());
  } catch (...) {
    state->fail("unknown exception", std::current_exception());
  }
  state->body = nullptr;  // release what the body captured, here on its own thread
  state->finish();
  return nullptr;
}

RtThread::~RtThread() {
  if (!joinable()) return;
  // Like std::thread: a thread cannot join itself (EDEADLK); the state it uses must not be
  // freed under it, so that is fatal.
  if (pthread_join(handle_, nullptr) != 0) std::terminate();
}

RtThread::RtThread(RtThread&& other) noexcept
    : spec_(std::move(other.spec_)),
      placement_(std::move(other.placement_)),
      state_(std::move(other.state_)),
      handle_(std::exchange(other.handle_, pthread_t{})),
      joined_(std::exchange(other.joined_, false)) {}

RtThread& RtThread::operator=(RtThread&& other) noexcept {
  if (this == &other) return *this;
  if (joinable() && pthread_join(handle_, nullptr) != 0) std::terminate();
  spec_ = std::move(other.spec_);
  placement_ = std::move(other.placement_);
  state_ = std::move(other.state_);
  handle_ = std::exchange(other.handle_, pthread_t{});
  joined_ = std::exchange(other.joined_, false);
  return *this;
}

void RtThread::join() {
  if (!joinable()) {
    throw std::system_error(std::make_error_code(std::errc::invalid_argument),
                            "RtThread '" + spec_.name + "': join: not joinable");
  }
  const int rc = pthread_join(handle_, nullptr);
  if (rc != 0) {
    throw std::system_error(rc, std::generic_category(),
                            "RtThread '" + spec_.name + "': pthread_join");
  }
  joined_ = true;
}

std::int64_t RtThread::cpu_time_ns() const {
  if (state_ == nullptr) return 0;
  if (state_->finished.load(std::memory_order_acquire)) return state_->final_cpu_ns;
  if (!state_->has_clock) return 0;
  timespec ts{};
  const bool read = clock_gettime(state_->clock, &ts) == 0;
  // The thread may have finished (and exited, its clock gone or its id reused) meanwhile: it
  // stored its final figure before, so that one is the answer.
  if (state_->finished.load(std::memory_order_acquire)) return state_->final_cpu_ns;
  return read ? timespec_to_ns(ts) : 0;
}

bool RtThread::finished() const {
  return state_ != nullptr && state_->finished.load(std::memory_order_acquire);
}

bool RtThread::failed() const {
  return state_ != nullptr && state_->failed.load(std::memory_order_acquire);
}

std::string RtThread::error() const { return failed() ? state_->error : std::string(); }

std::exception_ptr RtThread::exception() const {
  return failed() ? state_->exception : std::exception_ptr();
}

ScopedThreadPriority::ScopedThreadPriority(int priority, bool round_robin) {
  if (priority <= 0) return;
  sched_param old{};
  if (pthread_getschedparam(pthread_self(), &old_policy_, &old) != 0) return;
  old_priority_ = old.sched_priority;
  sched_param param{};
  param.sched_priority = priority;
  const int rc = pthread_setschedparam(pthread_self(), round_robin ? SCHED_RR : SCHED_FIFO, &param);
  if (rc == 0) {
    changed_ = true;
    placement_.fifo = true;
    placement_.round_robin = round_robin;
    placement_.priority = priority;
    return;
  }
  placement_.fallback = (round_robin ? "SCHED_RR " : "SCHED_FIFO ") + std::to_string(priority) +
                        (rc == EPERM ? " not permitted (" : " rejected (") + errno_name(rc) +
                        "): running SCHED_OTHER";
}

ScopedThreadPriority::~ScopedThreadPriority() {
  if (!changed_) return;
  sched_param old{};
  old.sched_priority = old_priority_;
  pthread_setschedparam(pthread_self(), old_policy_, &old);
}

MemoryLock lock_memory() {
  MemoryLock result;
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    result.locked = true;
    return result;
  }
  const int err = errno;
  result.warning = "mlockall: " + std::generic_category().message(err) + " (" + errno_name(err);
  if (err == EPERM || err == ENOMEM)
    result.warning += "; needs CAP_IPC_LOCK or a higher RLIMIT_MEMLOCK";
  result.warning += "): pages may fault in the fixed-rate threads";
  return result;
}

}  // namespace wallar::firmware
