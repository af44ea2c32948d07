// SPDX-License-Identifier: Apache-2.0
/// @file triple_buffer.hpp
/// @brief A "latest value" snapshot between one writer and one reader for large values (a map
/// snapshot, the wall model) that must be neither copied nor guarded by a lock.
///
/// Three slots, as in NewestMailbox: the writer fills its own slot in place (back()), then
/// publish() swaps it with the shared middle slot in one atomic exchange that also sets a
/// "fresh" bit; refresh() swaps the middle with the reader's slot only when the bit is set.
/// Neither side ever touches the other's slot, so neither waits for the other and nothing is
/// copied. Unlike the mailbox the reader keeps its value: front() stays valid and unchanged
/// until the next refresh() that returns true, and a refresh() with nothing new keeps it.
///
/// The writer does not get its last value back: after publish(), back() is whichever slot was
/// free, holding an older value (or the one `make` built). The writer must overwrite every
/// field it publishes (reusing the slot's storage, e.g. a vector's capacity, is the point).
/// Before the first refresh() that returns true, front() is the value `make` built.
///
/// Slots are built once in the constructor (by `make`, so they can be pre-sized); nothing
/// allocates afterwards unless T itself does when the writer fills it.
///
/// Threading: exactly one writer thread calls back()/publish(), exactly one reader thread
/// calls refresh()/front(); published() may be read from any thread.
#pragma once

#include <array>
#include <atomic>
#include <concepts>
#include <cstdint>
#include <type_traits>

namespace wallar {

template <typename T>
class TripleBuffer {
 public:
  /// Slots default-constructed.
  TripleBuffer() : TripleBuffer([] { return T{}; }) {}
  /// `make` is called three times, once per slot (sized storage).
  template <typename Make>
  requires std::invocable<Make&> && std::convertible_to<std::invoke_result_t<Make&>, T>
  explicit TripleBuffer(Make make) : slots_{make(), make(), make()} {}
  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  /// The writer's slot, to fill in place before publish(). Holds an older value, not the one
  /// last published. Writer thread only.
  T& back() { return slots_[back_]; }

  /// Makes the value in back() the newest one; back() moves to a free slot. Never waits.
  void publish() {
    const std::uint8_t old = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    back_ = old & kIndex;
    published_.fetch_add(1, std::memory_order_relaxed);
  }

  /// Takes the newest published value into front() if one arrived since the last refresh();
  /// returns whether front() changed. Never waits. Reader thread only.
  bool refresh() {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    const std::uint8_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = old & kIndex;
    return true;
  }

  /// The reader's value: valid and unchanged until the next refresh(). Reader thread only.
  [[nodiscard]] const T& front() const { return slots_[front_]; }

  /// The number of publish() calls so far.
  [[nodiscard]] std::uint64_t published() const {
    return published_.load(std::memory_order_relaxed);
  }

 private:
  static constexpr std::uint8_t kIndex = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;

  std::array<T, 3> slots_;
  alignas(64) std::uint8_t back_ = 0;   // writer's slot
  alignas(64) std::uint8_t front_ = 1;  // reader's slot
  alignas(64) std::atomic<std::uint8_t> middle_{2};
  std::atomic<std::uint64_t> published_{0};
};

}  // namespace wallar
