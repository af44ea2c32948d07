// SPDX-License-Identifier: Apache-2.0
/// @file log_ring.cpp
/// @brief The log ring (Vyukov's bounded MPMC queue, one consumer) and its low-priority thread.
#include "wallar/firmware/log_ring.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>

namespace wallar::firmware {

// Each conversion is formatted alone, with a spec cut from the record's static format and the
// argument whose kind matches the conversion (checked above each call): not a literal, on
// purpose.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wformat-nonliteral"
std::string format_log_record(const LogRecord& record) {
  std::string out;
  if (record.format == nullptr) return out;
  std::size_t next = 0;
  const char* p = record.format;
  char buf[LogRecord::kCopiedChars + 65];  // a copied text with a width to spare
  while (*p != '\0') {
    if (*p != '%') {
      out += *p++;
      continue;
    }
    if (p[1] == '%') {
      out += '%';
      p += 2;
      continue;
    }
    // One conversion: flags, width, precision, length, then the conversion character.
    const char* start = p++;
    while (*p != '\0' && std::strchr("-+ #0123456789.lhzjt", *p) != nullptr) ++p;
    if (*p == '\0') break;
    const char conv = *p++;
    std::string spec(start, static_cast<std::size_t>(p - start - 1));
    spec.erase(std::remove_if(spec.begin(), spec.end(),
                              [](char c) { return std::strchr("lhzjt", c) != nullptr; }),
               spec.end());
    const LogArg arg = next < record.args.size() ? record.args[next] : LogArg{};
    ++next;
    switch (conv) {
      case 's':
        if (arg.kind == LogArg::Kind::kText) {
          std::snprintf(buf, sizeof buf, (spec + "s").c_str(), arg.s != nullptr ? arg.s : "");
        } else if (arg.kind == LogArg::Kind::kErrno) {
          std::snprintf(buf, sizeof buf, (spec + "s").c_str(),
                        std::strerror(static_cast<int>(arg.i)));
        } else if (arg.kind == LogArg::Kind::kCopied) {
          std::snprintf(buf, sizeof buf, (spec + "s").c_str(), record.copied);
        } else {
          std::snprintf(buf, sizeof buf, "?");
        }
        break;
      case 'd':
      case 'i':
      case 'u':
      case 'x':
      case 'X':
        if (arg.kind == LogArg::Kind::kInt) {
          std::snprintf(buf, sizeof buf, (spec + "ll" + conv).c_str(),
                        static_cast<long long>(arg.i));
        } else {
          std::snprintf(buf, sizeof buf, "?");
        }
        break;
      case 'f':
      case 'g':
      case 'e':
        if (arg.kind == LogArg::Kind::kDouble || arg.kind == LogArg::Kind::kInt) {
          const double v = arg.kind == LogArg::Kind::kDouble ? arg.d : static_cast<double>(arg.i);
          std::snprintf(buf, sizeof buf, (spec + conv).c_str(), v);
        } else {
          std::snprintf(buf, sizeof buf, "?");
        }
        break;
      default:
        std::snprintf(buf, sizeof buf, "?");
        break;
    }
    out += buf;
  }
  return out;
}
#pragma GCC diagnostic pop

LogRing::LogRing(std::size_t capacity) {
  std::size_t n = 2;
  while (n < capacity) n *= 2;
  cells_ = std::make_unique<Cell[]>(n);
  for (std::size_t i = 0; i < n; ++i) cells_[i].seq.store(i, std::memory_order_relaxed);
  mask_ = n - 1;
}

namespace {

/// The record's format and arguments (at most kMaxArgs; the rest cleared).
void set_args(LogRecord& r, const char* format, std::initializer_list<LogArg> args) noexcept {
  r.format = format;
  std::size_t i = 0;
  for (const LogArg& a : args) {
    if (i == r.args.size()) break;
    r.args[i++] = a;
  }
  for (; i < r.args.size(); ++i) r.args[i] = LogArg{};
}

/// The record's copied text (cut at LogRecord::kCopiedChars), or none.
void set_copied(LogRecord& r, const char* copied) noexcept {
  r.copied[0] = '\0';
  if (copied == nullptr) return;
  const std::size_t n = strnlen(copied, LogRecord::kCopiedChars);
  std::memcpy(r.copied, copied, n);
  r.copied[n] = '\0';
}

}  // namespace

void post_or_log(LogRing* ring, const std::function<void(const std::string&)>& fallback,
                 const char* format, std::initializer_list<LogArg> args, const char* copied) {
  if (ring != nullptr) {
    ring->post(format, args, copied);
    return;
  }
  LogRecord r;
  set_args(r, format, args);
  set_copied(r, copied);
  fallback(format_log_record(r));
}

bool LogRing::post(const char* format, std::initializer_list<LogArg> args,
                   const char* copied) noexcept {
  std::size_t pos = enqueue_.load(std::memory_order_relaxed);
  Cell* cell = nullptr;
  for (;;) {
    cell = &cells_[pos & mask_];
    const std::size_t seq = cell->seq.load(std::memory_order_acquire);
    const auto diff = static_cast<std::intptr_t>(seq) - static_cast<std::intptr_t>(pos);
    if (diff == 0) {
      if (enqueue_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) break;
    } else if (diff < 0) {
      dropped_.fetch_add(1, std::memory_order_relaxed);  // full: the log thread is behind
      return false;
    } else {
      pos = enqueue_.load(std::memory_order_relaxed);
    }
  }
  LogRecord& r = cell->record;
  r.t_ns = monotonic_now_ns();
  set_args(r, format, args);
  set_copied(r, copied);
  cell->seq.store(pos + 1, std::memory_order_release);
  wakeup_.notify();
  return true;
}

bool LogRing::pop(LogRecord& out) noexcept {
  Cell& cell = cells_[dequeue_ & mask_];
  const std::size_t seq = cell.seq.load(std::memory_order_acquire);
  if (static_cast<std::intptr_t>(seq) - static_cast<std::intptr_t>(dequeue_ + 1) < 0) return false;
  out = cell.record;
  cell.seq.store(dequeue_ + mask_ + 1, std::memory_order_release);
  ++dequeue_;
  return true;
}

LogThread::LogThread(LogRing& ring, std::function<void(const std::string&)> sink, ThreadSpec spec,
                     Options options)
    : ring_(ring),
      sink_(std::move(sink)),
      options_(options),
      tokens_(static_cast<double>(options.burst)) {
  thread_ = std::make_unique<RtThread>(std::move(spec), [this] {
    while (!stop_.load(std::memory_order_acquire)) {
      ring_.wakeup().wait_for(100 * kNsPerMs);
      drain(monotonic_now_ns());
      const std::lock_guard<std::mutex> lock(report_mutex_);
      if (report_request_ != nullptr && report_request_->exchange(false) && make_report_) {
        report_out_(make_report_());
      }
    }
    drain(monotonic_now_ns());
    if (held_back_ > 0) {
      sink_("(" + std::to_string(held_back_) + " log lines held back)");
      held_back_ = 0;
    }
  });
}

LogThread::~LogThread() { stop(); }

void LogThread::stop() {
  if (!thread_ || !thread_->joinable()) return;
  stop_.store(true, std::memory_order_release);
  ring_.wakeup().notify();
  thread_->join();
}

void LogThread::set_report(std::atomic<bool>* request, std::function<std::string()> make,
                           std::function<void(const std::string&)> out) {
  const std::lock_guard<std::mutex> lock(report_mutex_);
  report_request_ = request;
  make_report_ = std::move(make);
  report_out_ = std::move(out);
}

void LogThread::drain(TimeNs now_ns) {
  if (last_refill_ns_ == 0) last_refill_ns_ = now_ns;
  tokens_ = std::min(static_cast<double>(options_.burst),
                     tokens_ + options_.per_s * ns_to_s(now_ns - last_refill_ns_));
  last_refill_ns_ = now_ns;
  LogRecord record;
  while (ring_.pop(record)) {
    if (tokens_ < 1.0) {
      ++held_back_;
      suppressed_total_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    if (held_back_ > 0) {
      sink_("(" + std::to_string(held_back_) + " log lines held back)");
      held_back_ = 0;
    }
    tokens_ -= 1.0;
    sink_(format_log_record(record));
  }
  const std::uint64_t dropped = ring_.dropped();
  if (dropped > dropped_said_) {
    sink_("(" + std::to_string(dropped - dropped_said_) +
          " log lines lost: the log ring was full)");
    dropped_said_ = dropped;
  }
}

}  // namespace wallar::firmware
