// SPDX-License-Identifier: Apache-2.0
/// @file spsc_ring.hpp
/// @brief A bounded single-producer/single-consumer lock-free ring with in-place slots
/// (after rigtorp/SPSCQueue: cached indices, one atomic per side on its own cache line).
///
/// Slots are allocated once in the constructor; the producer fills a slot in place
/// (producer_slot() then push()), the consumer reads it in place (front() then pop()). Nothing
/// allocates after construction, so large messages (a key-frame's observations, a map
/// correction) cross threads without copies or heap traffic.
///
/// Threading: exactly one producer thread calls producer_slot()/push(), exactly one consumer
/// thread calls front()/pop(); size_approx() may be called from anywhere.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>

namespace wallar {

template <typename T>
class SpscRing {
 public:
  /// `capacity` usable slots; `make` is called once per slot to build it (sized storage).
  template <typename Make>
  SpscRing(std::size_t capacity, Make make)
      : slots_(std::make_unique<T[]>(capacity + 1)), size_(capacity + 1) {
    for (std::size_t i = 0; i < size_; ++i) slots_[i] = make();
  }
  explicit SpscRing(std::size_t capacity) : SpscRing(capacity, [] { return T{}; }) {}

  /// The slot to fill next, or nullptr when the ring is full (the consumer is behind).
  T* producer_slot() {
    const std::size_t w = write_.load(std::memory_order_relaxed);
    const std::size_t next = w + 1 == size_ ? 0 : w + 1;
    if (next == read_cache_) {
      read_cache_ = read_.load(std::memory_order_acquire);
      if (next == read_cache_) return nullptr;
    }
    return &slots_[w];
  }
  /// Publishes the slot returned by producer_slot().
  void push() {
    const std::size_t w = write_.load(std::memory_order_relaxed);
    write_.store(w + 1 == size_ ? 0 : w + 1, std::memory_order_release);
  }

  /// The oldest published slot, or nullptr when empty.
  T* front() {
    const std::size_t r = read_.load(std::memory_order_relaxed);
    if (r == write_cache_) {
      write_cache_ = write_.load(std::memory_order_acquire);
      if (r == write_cache_) return nullptr;
    }
    return &slots_[r];
  }
  /// Releases the slot returned by front() back to the producer.
  void pop() {
    const std::size_t r = read_.load(std::memory_order_relaxed);
    read_.store(r + 1 == size_ ? 0 : r + 1, std::memory_order_release);
  }

  [[nodiscard]] std::size_t size_approx() const {
    const std::size_t w = write_.load(std::memory_order_acquire);
    const std::size_t r = read_.load(std::memory_order_acquire);
    return w >= r ? w - r : w + size_ - r;
  }
  [[nodiscard]] std::size_t capacity() const { return size_ - 1; }

 private:
  static constexpr std::size_t kLine = 64;
  std::unique_ptr<T[]> slots_;
  std::size_t size_;
  alignas(kLine) std::atomic<std::size_t> write_{0};
  alignas(kLine) std::size_t read_cache_ = 0;  //!< producer's copy of read_
  alignas(kLine) std::atomic<std::size_t> read_{0};
  alignas(kLine) std::size_t write_cache_ = 0;  //!< consumer's copy of write_
};

}  // namespace wallar
