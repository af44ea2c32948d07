// SPDX-License-Identifier: Apache-2.0
/// @file image.hpp
/// @brief Reference-counted image buffers: stages pass references, never pixel copies.
///
/// An ImageBuffer owns pixel memory (a heap block, a pool slot, or a V4L2 kernel buffer that
/// must be re-queued). Image is a counted reference to one: copying an Image bumps an atomic
/// count; when the last reference is dropped the buffer's release() runs on that thread.
///
/// Threading: an Image may be copied, moved and dropped on any thread; the pixels are
/// read-only once published. release() implementations must be thread-safe and must not block.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>

namespace wallar {

enum class PixelFormat : std::uint8_t {
  kGray8,  //!< one byte per pixel
  kYuyv,   //!< 4:2:2, two bytes per pixel
  kRgb8,   //!< three bytes per pixel
};

[[nodiscard]] constexpr int bytes_per_pixel(PixelFormat format) {
  switch (format) {
    case PixelFormat::kGray8:
      return 1;
    case PixelFormat::kYuyv:
      return 2;
    case PixelFormat::kRgb8:
      return 3;
  }
  return 1;
}

/// Memory that holds the pixels of one image, with an intrusive atomic reference count.
class ImageBuffer {
 public:
  ImageBuffer(const ImageBuffer&) = delete;
  ImageBuffer& operator=(const ImageBuffer&) = delete;

  [[nodiscard]] const std::uint8_t* data() const { return data_; }
  [[nodiscard]] std::uint8_t* mutable_data() { return data_; }
  [[nodiscard]] std::size_t size_bytes() const { return size_bytes_; }

  void add_ref() { refs_.fetch_add(1, std::memory_order_relaxed); }
  void drop_ref() {
    // acq_rel: the releasing thread must see every write other holders made to the pixels.
    if (refs_.fetch_sub(1, std::memory_order_acq_rel) == 1) release();
  }
  [[nodiscard]] int ref_count() const { return refs_.load(std::memory_order_acquire); }

 protected:
  ImageBuffer() = default;
  virtual ~ImageBuffer() = default;
  void set_memory(std::uint8_t* data, std::size_t size_bytes) {
    data_ = data;
    size_bytes_ = size_bytes;
  }
  /// Called once when the count reaches zero: free, return to a pool, or re-queue to a driver.
  virtual void release() = 0;

 private:
  std::uint8_t* data_ = nullptr;
  std::size_t size_bytes_ = 0;
  std::atomic<int> refs_{0};
};

/// A heap buffer that deletes itself when the last reference goes (replay, tools, tests).
class HeapImageBuffer final : public ImageBuffer {
 public:
  static ImageBuffer* create(std::size_t size_bytes) { return new HeapImageBuffer(size_bytes); }

 private:
  explicit HeapImageBuffer(std::size_t size_bytes)
      : storage_(std::make_unique<std::uint8_t[]>(size_bytes)) {
    set_memory(storage_.get(), size_bytes);
  }
  void release() override { delete this; }
  std::unique_ptr<std::uint8_t[]> storage_;
};

/// A counted reference to an image in an ImageBuffer, with its geometry.
class Image {
 public:
  Image() = default;
  Image(ImageBuffer* buffer, int width, int height, int stride_bytes, PixelFormat format)
      : buffer_(buffer), width_(width), height_(height), stride_(stride_bytes), format_(format) {
    if (buffer_ != nullptr) buffer_->add_ref();
  }
  /// A new gray/YUYV/RGB image in a fresh heap buffer with a tight stride.
  static Image allocate(int width, int height, PixelFormat format) {
    const int stride = width * bytes_per_pixel(format);
    return Image(HeapImageBuffer::create(static_cast<std::size_t>(stride) * height), width, height,
                 stride, format);
  }

  Image(const Image& other)
      : Image(other.buffer_, other.width_, other.height_, other.stride_, other.format_) {}
  Image(Image&& other) noexcept
      : buffer_(std::exchange(other.buffer_, nullptr)),
        width_(other.width_),
        height_(other.height_),
        stride_(other.stride_),
        format_(other.format_) {}
  Image& operator=(Image other) noexcept {
    swap(other);
    return *this;
  }
  ~Image() {
    if (buffer_ != nullptr) buffer_->drop_ref();
  }
  void swap(Image& other) noexcept {
    std::swap(buffer_, other.buffer_);
    std::swap(width_, other.width_);
    std::swap(height_, other.height_);
    std::swap(stride_, other.stride_);
    std::swap(format_, other.format_);
  }

  [[nodiscard]] bool empty() const { return buffer_ == nullptr; }
  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }
  [[nodiscard]] int stride_bytes() const { return stride_; }
  [[nodiscard]] PixelFormat format() const { return format_; }
  [[nodiscard]] const std::uint8_t* data() const { return buffer_ ? buffer_->data() : nullptr; }
  /// Writable pixels: only for the producer, before the image is published.
  [[nodiscard]] std::uint8_t* mutable_data() { return buffer_ ? buffer_->mutable_data() : nullptr; }
  [[nodiscard]] const std::uint8_t* row(int y) const {
    return data() + std::ptrdiff_t{y} * stride_;
  }
  [[nodiscard]] int use_count() const { return buffer_ ? buffer_->ref_count() : 0; }

 private:
  ImageBuffer* buffer_ = nullptr;
  int width_ = 0;
  int height_ = 0;
  int stride_ = 0;
  PixelFormat format_ = PixelFormat::kGray8;
};

}  // namespace wallar
