// SPDX-License-Identifier: Apache-2.0
/// @file jpeg.hpp
/// @brief JPEG through libjpeg-turbo: the Motion-JPEG frames of UVC cameras, and JPEG files
/// (calibration images). OpenCV's imgcodecs is not available on the arm64 build, libjpeg is.
///
/// UVC cameras usually send MJPEG frames without Huffman tables (DHT); libjpeg-turbo falls
/// back to the standard tables of JPEG Annex K.3 for them, as the UVC spec requires.
///
/// Allocation: libjpeg allocates its working memory per image (and frees it at the end of
/// each image) through malloc; it cannot be given a pool. Decoding MJPEG is therefore the one
/// capture path that allocates per frame; GREY and YUYV capture do not.
///
/// Threading: a JpegDecoder is used by one thread at a time; the free functions are
/// thread-safe.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "wallar/core/image.hpp"

namespace wallar::recording {

struct JpegSize {
  int width_px = 0;
  int height_px = 0;
};

/// A reusable decoder (one libjpeg decompress object kept across frames).
class JpegDecoder {
 public:
  JpegDecoder();
  ~JpegDecoder();
  JpegDecoder(const JpegDecoder&) = delete;
  JpegDecoder& operator=(const JpegDecoder&) = delete;

  /// Decodes `jpeg` to 8-bit gray into `out` (`stride_bytes` per row), which must have room for
  /// `expected` (the negotiated size). Returns false and sets `error` to one line on corrupt or
  /// truncated data, or on a size other than `expected`; `out` is then unspecified.
  bool decode_gray(std::span<const std::uint8_t> jpeg, JpegSize expected, std::uint8_t* out,
                   int stride_bytes, std::string& error);
  /// Reads the frame header only.
  bool read_size(std::span<const std::uint8_t> jpeg, JpegSize& size, std::string& error);

  struct State;

 private:
  std::unique_ptr<State> state_;
};

/// Loads a JPEG file as 8-bit gray (colour is converted). Throws InputError naming the file on
/// a missing, corrupt or (when expected sizes are > 0) wrongly sized image.
Image load_jpeg_gray(const std::filesystem::path& path, int expected_width = 0,
                     int expected_height = 0);
/// PNG or JPEG by the file's extension (.png, .jpg, .jpeg; any case); InputError otherwise.
Image load_image_gray(const std::filesystem::path& path, int expected_width = 0,
                      int expected_height = 0);
/// Encodes an 8-bit gray image as baseline JPEG (quality 1..100). When `omit_huffman_tables`
/// the DHT segment is left out, as UVC cameras do (tests of the MJPEG path). Throws
/// InputError on failure.
std::vector<std::uint8_t> encode_jpeg_gray(const Image& image, int quality,
                                           bool omit_huffman_tables = false);

}  // namespace wallar::recording
