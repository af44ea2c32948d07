// SPDX-License-Identifier: Apache-2.0
/// @file seqlock.hpp
/// @brief A sequence lock for small trivially copyable values (a pose, a clock offset, a set of
/// counters): one writer that never waits, any number of readers that retry while a store is
/// in progress.
///
/// The payload lives in an array of atomic 64-bit words, so every access is an atomic one and
/// the structure is data-race-free under the C++ memory model (and clean under ThreadSanitizer)
/// even while a reader overlaps a store. After H.-J. Boehm, "Can seqlocks get along with
/// programming language memory models?" (MSPC 2012): the writer makes the sequence odd, stores
/// the words with release (so the odd sequence is visible before any new word), then makes
/// the sequence even with a release store; a reader acquire-loads the sequence, loads the words
/// with acquire (so its re-read of the sequence cannot move before them) and re-reads the
/// sequence: an odd or changed sequence means the copy may be torn and is discarded. The same
/// orderings are compiled everywhere: ThreadSanitizer, which does not model stand-alone fences,
/// checks exactly what ships (the fence variant it could not check is gone). On x86 these are
/// plain moves; on AArch64 STLR/LDAR per word, a few ns for a pose.
///
/// Values are copied in and out with memcpy through a local word buffer: nothing allocates,
/// nothing blocks the writer. A reader spins (then yields) only while a store is in progress,
/// i.e. for the time it takes to copy sizeof(T) bytes. For large values (a map snapshot) use
/// TripleBuffer instead.
///
/// Threading: exactly one writer thread calls store(); any number of threads call load(),
/// try_load() and version() concurrently with it and with each other.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <thread>
#include <type_traits>

namespace wallar {

template <typename T>
class Seqlock {
  static_assert(std::is_trivially_copyable_v<T>, "Seqlock<T> copies T bytewise");
  static_assert(std::is_default_constructible_v<T>, "Seqlock<T>::load() returns a T");

 public:
  /// Holds T{} until the first store(); version() is 0.
  Seqlock() noexcept : Seqlock(T{}) {}
  /// Holds `initial` (not counted as a store); version() is 0.
  explicit Seqlock(const T& initial) noexcept {
    Words buf{};
    std::memcpy(buf.data(), &initial, sizeof(T));
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(buf[i], std::memory_order_relaxed);
  }
  Seqlock(const Seqlock&) = delete;
  Seqlock& operator=(const Seqlock&) = delete;

  /// Publishes `value`. Writer thread only; never waits for readers.
  void store(const T& value) noexcept {
    Words buf{};
    std::memcpy(buf.data(), &value, sizeof(T));
    const std::uint64_t seq = seq_.load(std::memory_order_relaxed);
    seq_.store(seq + 1, std::memory_order_relaxed);  // odd: a store is in progress
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(buf[i], std::memory_order_release);
    seq_.store(seq + 2, std::memory_order_release);
  }

  /// One attempt: copies the current value into `out` and returns true, or returns false
  /// (leaving `out` untouched) when a store was in progress or completed during the copy.
  [[nodiscard]] bool try_load(T& out) const noexcept {
    const std::uint64_t before = seq_.load(std::memory_order_acquire);
    if ((before & 1U) != 0) return false;
    Words buf;
    for (std::size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_acquire);
    if (seq_.load(std::memory_order_relaxed) != before) return false;
    std::memcpy(static_cast<void*>(&out), buf.data(), sizeof(T));
    return true;
  }

  /// The current value; retries while a store is in progress (spins briefly, then yields).
  [[nodiscard]] T load() const noexcept {
    T out{};
    for (unsigned attempt = 0; !try_load(out); ++attempt) {
      if (attempt < kSpinsBeforeYield) {
        cpu_relax();
      } else {
        std::this_thread::yield();  // the writer may have been preempted mid-store
      }
    }
    return out;
  }

  /// The number of completed store() calls (a store in progress is not counted).
  [[nodiscard]] std::uint64_t version() const noexcept {
    return seq_.load(std::memory_order_acquire) / 2;
  }

 private:
  static constexpr std::size_t kWords = (sizeof(T) + sizeof(std::uint64_t) - 1) / 8;
  static constexpr unsigned kSpinsBeforeYield = 64;
  using Words = std::array<std::uint64_t, kWords>;

  static void cpu_relax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
    asm volatile("yield" ::: "memory");
#endif
  }

  alignas(64) std::atomic<std::uint64_t> seq_{0};  //!< 2 * stores, +1 while a store runs
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

}  // namespace wallar

