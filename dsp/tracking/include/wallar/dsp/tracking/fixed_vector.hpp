// SPDX-License-Identifier: Apache-2.0
/// @file fixed_vector.hpp
/// @brief The tracker's static storage: a vector whose capacity is fixed once, at start-up.
///
/// FixedVector<T> allocates its capacity in the constructor (sized from the board file) and never
/// again: push_back on a full vector returns false instead of growing, so the fixed-rate
/// tracking path cannot allocate by accident. T must be default-constructible; clear() and
/// resize() only move the size.
///
/// Threading: none; one owner.
#pragma once

#include <cassert>
#include <cstddef>
#include <memory>
#include <span>

namespace wallar::dsp {

template <typename T>
class FixedVector {
 public:
  FixedVector() = default;
  explicit FixedVector(std::size_t capacity)
      : data_(std::make_unique<T[]>(capacity)), capacity_(capacity) {}

  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] std::size_t capacity() const { return capacity_; }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  [[nodiscard]] bool full() const { return size_ == capacity_; }

  /// Appends a copy; false (and nothing changes) when full.
  bool push_back(const T& value) {
    if (size_ == capacity_) return false;
    data_[size_++] = value;
    return true;
  }
  void pop_back() {
    assert(size_ > 0);
    --size_;
  }
  void clear() { size_ = 0; }
  /// Sets the size to min(n, capacity); new elements keep whatever they held.
  void resize(std::size_t n) { size_ = n < capacity_ ? n : capacity_; }

  T& operator[](std::size_t i) {
    assert(i < size_);
    return data_[i];
  }
  const T& operator[](std::size_t i) const {
    assert(i < size_);
    return data_[i];
  }
  T& back() { return (*this)[size_ - 1]; }
  T* begin() { return data_.get(); }
  T* end() { return data_.get() + size_; }
  const T* begin() const { return data_.get(); }
  const T* end() const { return data_.get() + size_; }
  [[nodiscard]] std::span<T> span() { return {data_.get(), size_}; }
  [[nodiscard]] std::span<const T> span() const { return {data_.get(), size_}; }

 private:
  std::unique_ptr<T[]> data_;
  std::size_t capacity_ = 0;
  std::size_t size_ = 0;
};

}  // namespace wallar::dsp
