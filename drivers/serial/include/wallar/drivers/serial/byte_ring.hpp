// SPDX-License-Identifier: Apache-2.0
/// @file byte_ring.hpp
/// @brief A fixed-capacity byte ring for reassembling serial frames, with start-byte resync.
///
/// Serial bytes arrive in arbitrary pieces: a frame split over two reads, garbage before a
/// start byte (line noise, a response to an abandoned request, a boot banner). The ring keeps
/// the bytes not yet parsed; resync() drops bytes until one a predicate accepts as a start
/// byte is at the front and counts what it dropped. Nothing allocates: capacity is a template
/// parameter.
///
/// Threading: a plain value owned by one thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace wallar::drivers {

template <std::size_t Capacity>
class ByteRing {
  static_assert(Capacity > 0 && (Capacity & (Capacity - 1)) == 0, "capacity: a power of two");

 public:
  /// Appends as many bytes as fit; the rest are dropped and counted in overflow_bytes().
  std::size_t push(std::span<const std::uint8_t> bytes) {
    std::size_t n = 0;
    for (std::uint8_t b : bytes) {
      if (size_ == Capacity) break;
      buf_[(head_ + size_) & kMask] = b;
      ++size_;
      ++n;
    }
    overflow_bytes_ += bytes.size() - n;
    return n;
  }

  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  [[nodiscard]] static constexpr std::size_t capacity() { return Capacity; }
  [[nodiscard]] std::size_t free_space() const { return Capacity - size_; }

  /// The i-th byte from the front (i < size()).
  [[nodiscard]] std::uint8_t operator[](std::size_t i) const { return buf_[(head_ + i) & kMask]; }

  /// Copies out.size() bytes starting `offset` bytes from the front (offset + out.size()
  /// <= size()).
  void copy_out(std::size_t offset, std::span<std::uint8_t> out) const {
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = (*this)[offset + i];
  }

  /// Removes n bytes from the front (a parsed frame): not counted as dropped.
  void consume(std::size_t n) {
    if (n > size_) n = size_;
    head_ = (head_ + n) & kMask;
    size_ -= n;
  }

  /// Drops n bytes from the front as garbage (counted).
  std::size_t drop(std::size_t n) {
    if (n > size_) n = size_;
    consume(n);
    dropped_bytes_ += n;
    return n;
  }

  /// Drops everything (counted as garbage). Returns how many bytes that was.
  std::size_t drop_all() { return drop(size_); }

  /// Drops bytes from the front until is_start(front) holds or the ring is empty; returns the
  /// number dropped (also added to dropped_bytes()).
  template <class IsStart>
  std::size_t resync(IsStart is_start) {
    std::size_t n = 0;
    while (size_ > 0 && !is_start((*this)[0])) {
      consume(1);
      ++n;
    }
    dropped_bytes_ += n;
    return n;
  }

  /// Total bytes dropped as garbage by drop()/drop_all()/resync().
  [[nodiscard]] std::uint64_t dropped_bytes() const { return dropped_bytes_; }
  /// Total bytes push() could not store because the ring was full.
  [[nodiscard]] std::uint64_t overflow_bytes() const { return overflow_bytes_; }

 private:
  static constexpr std::size_t kMask = Capacity - 1;
  std::array<std::uint8_t, Capacity> buf_{};
  std::size_t head_ = 0;
  std::size_t size_ = 0;
  std::uint64_t dropped_bytes_ = 0;
  std::uint64_t overflow_bytes_ = 0;
};

}  // namespace wallar::drivers
