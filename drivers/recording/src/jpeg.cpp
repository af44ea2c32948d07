// SPDX-License-Identifier: Apache-2.0
/// @file jpeg.cpp
/// @brief libjpeg-turbo decode/encode. libjpeg reports fatal errors through error_exit, which
/// must not return: it longjmps back into the function that called libjpeg. Those functions
/// hold only trivially destructible locals between setjmp and the libjpeg calls, so the jump
/// skips no destructor.
#include "wallar/drivers/recording/jpeg.hpp"

#include <jpeglib.h>

#include <algorithm>
#include <csetjmp>
#include <cstdio>
#include <fstream>
#include <iterator>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"

namespace wallar::recording {
namespace {

struct ErrorManager {
  jpeg_error_mgr pub;  // first member: libjpeg hands back a pointer to it
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void on_error_exit(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<ErrorManager*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}

// Warnings (corrupt entropy data, premature end of data) make a frame untrustworthy: keep the
// first one's text and count them; the callers treat any warning as a failed decode.
void on_emit_message(j_common_ptr cinfo, int msg_level) {
  if (msg_level >= 0) return;  // trace messages
  auto* err = reinterpret_cast<ErrorManager*>(cinfo->err);
  if (cinfo->err->num_warnings++ == 0) (*cinfo->err->format_message)(cinfo, err->message);
}

void install(ErrorManager& err) {
  jpeg_std_error(&err.pub);
  err.pub.error_exit = on_error_exit;
  err.pub.emit_message = on_emit_message;
  err.message[0] = '\0';
}

}  // namespace

struct JpegDecoder::State {
  ErrorManager err;
  jpeg_decompress_struct cinfo;
};

JpegDecoder::JpegDecoder() : state_(std::make_unique<State>()) {
  install(state_->err);
  state_->cinfo.err = &state_->err.pub;
  jpeg_create_decompress(&state_->cinfo);
}

JpegDecoder::~JpegDecoder() { jpeg_destroy_decompress(&state_->cinfo); }

namespace {

// 0 on success, 1 on a libjpeg error, 2 on a size mismatch. Only trivially destructible
// locals here (see the file comment).
int decode_into(JpegDecoder::State& s, const std::uint8_t* data, std::size_t size,
                JpegSize expected, std::uint8_t* out, int stride, bool header_only, JpegSize* got) {
  jpeg_decompress_struct& cinfo = s.cinfo;
  s.err.pub.num_warnings = 0;
  s.err.message[0] = '\0';
  if (setjmp(s.err.jump) != 0) {
    jpeg_abort_decompress(&cinfo);
    return 1;
  }
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  got->width_px = static_cast<int>(cinfo.image_width);
  got->height_px = static_cast<int>(cinfo.image_height);
  if (header_only) {
    jpeg_abort_decompress(&cinfo);
    return 0;
  }
  if (got->width_px != expected.width_px || got->height_px != expected.height_px) {
    jpeg_abort_decompress(&cinfo);
    return 2;
  }
  cinfo.out_color_space = JCS_GRAYSCALE;
  cinfo.dct_method = JDCT_ISLOW;
  jpeg_start_decompress(&cinfo);
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = out + static_cast<std::ptrdiff_t>(cinfo.output_scanline) * stride;
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  return 0;
}

}  // namespace

bool JpegDecoder::decode_gray(std::span<const std::uint8_t> jpeg, JpegSize expected,
                              std::uint8_t* out, int stride_bytes, std::string& error) {
  if (jpeg.size() < 4) {
    error = "JPEG data too short (" + std::to_string(jpeg.size()) + " bytes)";
    return false;
  }
  JpegSize got;
  const int rc =
      decode_into(*state_, jpeg.data(), jpeg.size(), expected, out, stride_bytes, false, &got);
  if (rc == 1) {
    error = std::string("corrupt JPEG: ") + state_->err.message;
    return false;
  }
  if (rc == 2) {
    error = "JPEG is " + std::to_string(got.width_px) + "x" + std::to_string(got.height_px) +
            ", expected " + std::to_string(expected.width_px) + "x" +
            std::to_string(expected.height_px);
    return false;
  }
  if (state_->err.pub.num_warnings > 0) {
    error = std::string("corrupt JPEG: ") + state_->err.message;
    return false;
  }
  return true;
}

bool JpegDecoder::read_size(std::span<const std::uint8_t> jpeg, JpegSize& size,
                            std::string& error) {
  if (jpeg.size() < 4) {
    error = "JPEG data too short (" + std::to_string(jpeg.size()) + " bytes)";
    return false;
  }
  if (decode_into(*state_, jpeg.data(), jpeg.size(), {}, nullptr, 0, true, &size) != 0) {
    error = std::string("corrupt JPEG: ") + state_->err.message;
    return false;
  }
  return true;
}

Image load_jpeg_gray(const std::filesystem::path& path, int expected_width, int expected_height) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path.string(), 0, "no such image file");
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  JpegDecoder decoder;
  JpegSize size;
  std::string error;
  if (!decoder.read_size(bytes, size, error)) throw_input_error(path.string(), 0, error);
  if ((expected_width > 0 && size.width_px != expected_width) ||
      (expected_height > 0 && size.height_px != expected_height)) {
    throw_input_error(path.string(), 0,
                      "image is " + std::to_string(size.width_px) + "x" +
                          std::to_string(size.height_px) + ", expected " +
                          std::to_string(expected_width) + "x" + std::to_string(expected_height));
  }
  if (size.width_px <= 0 || size.height_px <= 0 || size.width_px > 16384 ||
      size.height_px > 16384) {
    throw_input_error(path.string(), 0, "implausible JPEG size");
  }
  Image image = Image::allocate(size.width_px, size.height_px, PixelFormat::kGray8);
  if (!decoder.decode_gray(bytes, size, image.mutable_data(), image.stride_bytes(), error))
    throw_input_error(path.string(), 0, error);
  return image;
}

Image load_image_gray(const std::filesystem::path& path, int expected_width, int expected_height) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".png") return load_png_gray(path, expected_width, expected_height);
  if (ext == ".jpg" || ext == ".jpeg") return load_jpeg_gray(path, expected_width, expected_height);
  throw_input_error(path.string(), 0, "unsupported image type '" + ext + "' (PNG or JPEG)");
}

namespace {

struct EncodeState {
  ErrorManager err;
  jpeg_compress_struct cinfo;
  unsigned char* buffer = nullptr;
  unsigned long size = 0;  // NOLINT(google-runtime-int): libjpeg's type
};

// 0 on success. Trivially destructible locals only (see the file comment).
int encode_into(EncodeState& s, const Image& image, int quality, bool omit_huffman_tables) {
  jpeg_compress_struct& cinfo = s.cinfo;
  if (setjmp(s.err.jump) != 0) return 1;
  jpeg_mem_dest(&cinfo, &s.buffer, &s.size);
  cinfo.image_width = static_cast<JDIMENSION>(image.width());
  cinfo.image_height = static_cast<JDIMENSION>(image.height());
  cinfo.input_components = 1;
  cinfo.in_color_space = JCS_GRAYSCALE;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  cinfo.optimize_coding = FALSE;
  if (omit_huffman_tables) {
    // Mark the (standard) Huffman tables as already sent: jpeg_start_compress(.., FALSE) then
    // writes only the quantisation tables, like a UVC camera's MJPEG frame.
    jpeg_suppress_tables(&cinfo, TRUE);
    for (JQUANT_TBL* q : cinfo.quant_tbl_ptrs)
      if (q != nullptr) q->sent_table = FALSE;
  }
  jpeg_start_compress(&cinfo, omit_huffman_tables ? FALSE : TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    // libjpeg's API takes non-const rows; it does not write through them.
    auto* row = const_cast<JSAMPROW>(image.row(static_cast<int>(cinfo.next_scanline)));
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  return 0;
}

}  // namespace

std::vector<std::uint8_t> encode_jpeg_gray(const Image& image, int quality,
                                           bool omit_huffman_tables) {
  if (image.empty() || image.format() != PixelFormat::kGray8)
    throw_input_error("jpeg", 0, "only 8-bit gray images can be encoded");
  EncodeState s;
  install(s.err);
  s.cinfo.err = &s.err.pub;
  jpeg_create_compress(&s.cinfo);
  const int rc = encode_into(s, image, std::clamp(quality, 1, 100), omit_huffman_tables);
  jpeg_destroy_compress(&s.cinfo);
  std::vector<std::uint8_t> out;
  if (rc == 0 && s.buffer != nullptr) out.assign(s.buffer, s.buffer + s.size);
  std::free(s.buffer);  // NOLINT(cppcoreguidelines-no-malloc): jpeg_mem_dest mallocs it
  if (rc != 0) throw_input_error("jpeg", 0, std::string("JPEG encoding failed: ") + s.err.message);
  return out;
}

}  // namespace wallar::recording
