// SPDX-License-Identifier: Apache-2.0
/// @file log_ring.hpp
/// @brief Logging from the fixed-rate threads without formatting or stdio on them: a thread
/// posts a record (a static printf format and up to six arguments: numbers, static strings,
/// an errno, one short string copied in) into a lock-free ring, and a low-priority log thread
/// formats and writes it, at most a burst of lines then a steady rate (the journal on a
/// headset is flash: a flapping device must not fill it), saying how many it held back.
///
/// The ring is Vyukov's bounded multi-producer queue: a post is one CAS and a copy of the
/// record; a full ring drops the record and counts it (a logging thread never waits). Text
/// arguments are pointers, so they must outlive the log thread's drain: string literals, or
/// strings owned by modules that stop after the log thread (the appliance stops it first).
///
/// Threading: post() from any number of threads (never blocks, never allocates); pop() from
/// one consumer; LogThread's constructor and stop() from the owning thread.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "wallar/core/time.hpp"
#include "wallar/firmware/rt_thread.hpp"
#include "wallar/firmware/wakeup.hpp"

namespace wallar::firmware {

/// One argument of a record.
struct LogArg {
  enum class Kind : std::uint8_t { kNone, kInt, kDouble, kText, kErrno, kCopied };
  Kind kind = Kind::kNone;
  std::int64_t i = 0;
  double d = 0.0;
  const char* s = nullptr;

  LogArg() = default;
  LogArg(int v) : kind(Kind::kInt), i(v) {}                   // NOLINT: implicit by design
  LogArg(long v) : kind(Kind::kInt), i(v) {}                  // NOLINT
  LogArg(long long v) : kind(Kind::kInt), i(v) {}             // NOLINT
  LogArg(unsigned v) : kind(Kind::kInt), i(v) {}              // NOLINT
  LogArg(unsigned long v)                                     // NOLINT
      : kind(Kind::kInt), i(static_cast<std::int64_t>(v)) {}  // NOLINT
  LogArg(double v) : kind(Kind::kDouble), d(v) {}             // NOLINT
  LogArg(const char* v) : kind(Kind::kText), s(v) {}          // NOLINT
  /// strerror(err) for a %s, formatted by the log thread.
  static LogArg error(int err) {
    LogArg a;
    a.kind = Kind::kErrno;
    a.i = err;
    return a;
  }
  /// A string that does not live long enough (a device's last error): copied into the record
  /// (at most LogRecord::kCopiedChars), for a %s. One per record.
  static LogArg copied() {
    LogArg a;
    a.kind = Kind::kCopied;
    return a;
  }
};

struct LogRecord {
  static constexpr std::size_t kMaxArgs = 6;
  static constexpr std::size_t kCopiedChars = 191;  // two by-path device names
  TimeNs t_ns = 0;
  const char* format = nullptr;  //!< static; %s, %d/%lld-style and %f/%g-style conversions
  std::array<LogArg, kMaxArgs> args{};
  char copied[kCopiedChars + 1] = {};  //!< the LogArg::copied() argument's text
};

/// The line a record stands for (the log thread's work; allocates).
std::string format_log_record(const LogRecord& record);

class LogRing;
/// One line: a record in `ring` when there is one (a fixed-rate thread formats nothing), else
/// formatted here as the log thread would and handed to `fallback` (commands that run no log
/// thread: record, imu). At most LogRecord::kMaxArgs arguments; `copied`: the text of a
/// LogArg::copied() argument.
void post_or_log(LogRing* ring, const std::function<void(const std::string&)>& fallback,
                 const char* format, std::initializer_list<LogArg> args,
                 const char* copied = nullptr);

class LogRing {
 public:
  /// `capacity` is rounded up to a power of two; allocated here, once.
  explicit LogRing(std::size_t capacity = 256);
  LogRing(const LogRing&) = delete;
  LogRing& operator=(const LogRing&) = delete;

  /// Posts a record; false (counted in dropped()) when the ring is full. `copied` is the text
  /// of a LogArg::copied() argument. Never blocks, never allocates, never formats.
  bool post(const char* format, std::initializer_list<LogArg> args = {},
            const char* copied = nullptr) noexcept;
  /// The oldest record; false when none. One consumer.
  bool pop(LogRecord& out) noexcept;
  [[nodiscard]] std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  /// Notified after every post (async-signal-safe): the log thread sleeps on it.
  [[nodiscard]] Wakeup& wakeup() { return wakeup_; }

 private:
  struct Cell {
    std::atomic<std::size_t> seq{0};
    LogRecord record;
  };
  std::unique_ptr<Cell[]> cells_;
  std::size_t mask_;
  alignas(64) std::atomic<std::size_t> enqueue_{0};
  alignas(64) std::size_t dequeue_ = 0;
  std::atomic<std::uint64_t> dropped_{0};
  Wakeup wakeup_;
};

/// The low-priority thread that drains a ring into `sink`, one formatted line per record, at
/// most `burst` lines at once and `per_s` lines a second after that; the lines held back are
/// counted and said in one line when lines flow again.
class LogThread {
 public:
  struct Options {
    int burst = 100;
    double per_s = 20.0;
  };
  LogThread(LogRing& ring, std::function<void(const std::string&)> sink, ThreadSpec spec,
            Options options);
  ~LogThread();
  LogThread(const LogThread&) = delete;
  LogThread& operator=(const LogThread&) = delete;
  /// Drains what is left and ends the thread (once).
  void stop();
  /// A report made on this thread when asked: whenever *request is found set (by anyone, a
  /// signal handler included; polled at each wake-up, at least every 100 ms) it is cleared,
  /// `make` formats the report and `out` writes it, so that a SCHED_FIFO thread never formats
  /// it (the SIGUSR1 stats table). set_report(nullptr, {}, {}) before what `make` reads is
  /// gone: it waits for a report being made to finish.
  void set_report(std::atomic<bool>* request, std::function<std::string()> make,
                  std::function<void(const std::string&)> out);
  [[nodiscard]] std::uint64_t suppressed() const {
    return suppressed_total_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] const RtThread& thread() const { return *thread_; }

 private:
  void drain(TimeNs now_ns);

  LogRing& ring_;
  std::function<void(const std::string&)> sink_;
  Options options_;
  double tokens_;
  TimeNs last_refill_ns_ = 0;
  std::uint64_t held_back_ = 0;  //!< since the last line written
  std::uint64_t dropped_said_ = 0;
  std::atomic<std::uint64_t> suppressed_total_{0};
  std::atomic<bool> stop_{false};
  std::mutex report_mutex_;  // the supervisor sets, the log thread runs
  std::atomic<bool>* report_request_ = nullptr;
  std::function<std::string()> make_report_;
  std::function<void(const std::string&)> report_out_;
  std::unique_ptr<RtThread> thread_;
};

}  // namespace wallar::firmware
