// SPDX-License-Identifier: Apache-2.0
/// @file test_jpeg.cpp
/// @brief libjpeg path: round trip, UVC-style MJPEG without Huffman tables, corrupt and
/// truncated frames, wrong sizes, and files.
#include <cmath>

#include "test_support.hpp"
#include "wallar/drivers/recording/jpeg.hpp"

namespace wallar::test {
namespace {

using recording::JpegDecoder;
using recording::JpegSize;

// A smooth gradient with a few edges: compresses well, so quality 95 stays within a few grey
// levels everywhere.
Image test_pattern(int w, int h) {
  Image img = Image::allocate(w, h, PixelFormat::kGray8);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.mutable_data()[y * img.stride_bytes() + x] =
          static_cast<std::uint8_t>((x * 2 + y) % 200 + ((x / 40 + y / 40) % 2) * 40);
  return img;
}

double mean_abs_diff(const Image& a, const std::vector<std::uint8_t>& b) {
  double sum = 0.0;
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x)
      sum += std::abs(int{a.row(y)[x]} - int{b[static_cast<std::size_t>(y * a.width() + x)]});
  return sum / (a.width() * a.height());
}

TEST(Jpeg, RoundTripsAGrayImage) {
  const Image img = test_pattern(64, 48);
  const auto bytes = recording::encode_jpeg_gray(img, 95);
  JpegDecoder decoder;
  JpegSize size;
  std::string error;
  ASSERT_TRUE(decoder.read_size(bytes, size, error)) << error;
  EXPECT_EQ(size.width_px, 64);
  EXPECT_EQ(size.height_px, 48);
  std::vector<std::uint8_t> out(64 * 48);
  ASSERT_TRUE(decoder.decode_gray(bytes, {64, 48}, out.data(), 64, error)) << error;
  EXPECT_LT(mean_abs_diff(img, out), 2.0);
}

TEST(Jpeg, DecodesUvcStyleFramesWithoutHuffmanTables) {
  const Image img = test_pattern(64, 48);
  const auto with = recording::encode_jpeg_gray(img, 90);
  const auto without = recording::encode_jpeg_gray(img, 90, /*omit_huffman_tables=*/true);
  // The DHT marker (FF C4) is gone, and the frame is that much shorter.
  const auto has_dht = [](const std::vector<std::uint8_t>& b) {
    for (std::size_t i = 0; i + 1 < b.size(); ++i)
      if (b[i] == 0xFF && b[i + 1] == 0xC4) return true;
    return false;
  };
  EXPECT_TRUE(has_dht(with));
  EXPECT_FALSE(has_dht(without));
  EXPECT_LT(without.size(), with.size());
  JpegDecoder decoder;
  std::string error;
  std::vector<std::uint8_t> a(64 * 48), b(64 * 48);
  ASSERT_TRUE(decoder.decode_gray(with, {64, 48}, a.data(), 64, error)) << error;
  ASSERT_TRUE(decoder.decode_gray(without, {64, 48}, b.data(), 64, error)) << error;
  EXPECT_EQ(a, b);
}

TEST(Jpeg, RejectsTruncatedCorruptAndMissizedFramesAndRecovers) {
  const Image img = test_pattern(64, 48);
  const auto bytes = recording::encode_jpeg_gray(img, 90);
  JpegDecoder decoder;
  std::string error;
  std::vector<std::uint8_t> out(64 * 48);
  const std::vector<std::uint8_t> truncated(bytes.begin(), bytes.begin() + bytes.size() / 2);
  EXPECT_FALSE(decoder.decode_gray(truncated, {64, 48}, out.data(), 64, error));
  EXPECT_THAT(error, ::testing::HasSubstr("corrupt JPEG"));
  std::vector<std::uint8_t> garbage(200, 0x55);
  EXPECT_FALSE(decoder.decode_gray(garbage, {64, 48}, out.data(), 64, error));
  EXPECT_THAT(error, ::testing::HasSubstr("corrupt JPEG"));
  EXPECT_FALSE(decoder.decode_gray(bytes, {640, 480}, out.data(), 64, error));
  EXPECT_THAT(error, ::testing::HasSubstr("JPEG is 64x48, expected 640x480"));
  EXPECT_FALSE(decoder.decode_gray({}, {64, 48}, out.data(), 64, error));
  // The same decoder still decodes a good frame after each failure.
  error.clear();
  EXPECT_TRUE(decoder.decode_gray(bytes, {64, 48}, out.data(), 64, error)) << error;
}

TEST(Jpeg, LoadsFilesByExtensionWithOneLineErrors) {
  TempDir dir;
  const Image img = test_pattern(32, 24);
  const auto bytes = recording::encode_jpeg_gray(img, 95);
  spit(dir.path() / "a.JPG", std::string(bytes.begin(), bytes.end()));
  const Image loaded = recording::load_image_gray(dir.path() / "a.JPG");
  EXPECT_EQ(loaded.width(), 32);
  EXPECT_EQ(loaded.height(), 24);
  const auto error_of = [&](const char* name, int w = 0, int h = 0) {
    return input_error_of([&] { (void)recording::load_image_gray(dir.path() / name, w, h); });
  };
  EXPECT_THAT(error_of("a.JPG", 64, 48),
              ::testing::HasSubstr("a.JPG: image is 32x24, expected 64x48"));
  spit(dir.path() / "b.jpg", "not a jpeg at all");
  EXPECT_THAT(error_of("b.jpg"), ::testing::HasSubstr("corrupt JPEG"));
  EXPECT_THAT(error_of("c.bmp"), ::testing::HasSubstr("unsupported image type '.bmp'"));
  EXPECT_THAT(error_of("d.jpg"), ::testing::HasSubstr("no such image file"));
}

}  // namespace
}  // namespace wallar::test
