// SPDX-License-Identifier: Apache-2.0
/// @file mailbox.hpp
/// @brief A newest-only mailbox between one producer and one consumer: the producer never
/// waits, the consumer gets the most recent value, values it missed are counted.
///
/// Three slots (a triple buffer): the producer writes its own slot, then swaps it with the
/// shared middle slot in one atomic exchange that also sets a "fresh" bit; the consumer swaps
/// the middle with its own slot only when the bit is set. Neither side ever touches the other's
/// slot, so no lock is needed and neither can block the other. A value the consumer did not
/// take before the next post is overwritten: its resources (for frames: kernel buffers) are
/// released on the producer's thread at the next post, at most one post later.
///
/// For camera frames toward the tracker: capture never stalls behind a slow consumer, and the
/// consumer holds at most one frame (the one it took) besides the one waiting.
///
/// Threading: exactly one producer thread calls post(), exactly one consumer thread calls
/// take(); overwritten() may be read from any thread. T must be default-constructible and
/// move-assignable; with T = StereoFrame nothing allocates.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace wallar {

template <typename T>
class NewestMailbox {
 public:
  /// Publishes `value`, replacing one the consumer has not taken yet (counted).
  void post(T value) {
    slots_[back_] = std::move(value);
    const std::uint8_t old = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    if ((old & kFresh) != 0) overwritten_.fetch_add(1, std::memory_order_relaxed);
    back_ = old & kIndex;
    slots_[back_] = T{};  // drop what the consumer never took, here on the producer's thread
  }

  /// Moves the newest value into `out` if one arrived since the last take; false otherwise.
  bool take(T& out) {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    const std::uint8_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = old & kIndex;
    out = std::move(slots_[front_]);
    slots_[front_] = T{};
    return true;
  }

  /// Values posted but never taken.
  [[nodiscard]] std::uint64_t overwritten() const {
    return overwritten_.load(std::memory_order_relaxed);
  }

 private:
  static constexpr std::uint8_t kIndex = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;

  std::array<T, 3> slots_{};
  alignas(64) std::uint8_t back_ = 0;   // producer's slot
  alignas(64) std::uint8_t front_ = 1;  // consumer's slot
  alignas(64) std::atomic<std::uint8_t> middle_{2};
  std::atomic<std::uint64_t> overwritten_{0};
};

}  // namespace wallar
