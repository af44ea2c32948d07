// SPDX-License-Identifier: Apache-2.0
/// @file test_cloud_io.cpp
/// @brief The point-cloud readers (PLY, PCD, CSV) and the PLY writer: every format and encoding
/// round-trips a small known cloud (binary files are built byte by byte here, the LZF stream by
/// a tiny compressor with real back-references), the real PCL reference cloud reads as PCL says,
/// and every kind of bad input ends in one InputError line naming the file (and the line).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "wallar/drivers/cloud/cloud_io.hpp"

namespace wallar::test {
namespace {

using cloud::CloudReadStats;
using cloud::parse_pcd;
using cloud::parse_ply;
using cloud::parse_xyz_csv;
using cloud::read_cloud;
using ::testing::HasSubstr;

// ---------------------------------------------------------------------------------------------
// The known cloud and byte builders

struct Pt {
  float x, y, z, w;
  std::uint16_t obs;
};

// Dyadic values: exact in float, double and short decimal text.
const std::vector<Pt> kPts = {
    {0.5F, -1.25F, 2.0F, 0.75F, 3},
    {0.0625F, 4.5F, -0.75F, 0.5F, 1},
    {-2.5F, 0.0F, 1.5F, 1.0F, 12},
    {3.25F, -0.5F, 0.125F, 0.25F, 700},
};

void expect_known(const PointCloud& c, bool weight, bool obs) {
  ASSERT_EQ(c.size(), kPts.size());
  ASSERT_TRUE(c.consistent());
  EXPECT_EQ(c.has_weight(), weight);
  EXPECT_EQ(c.has_observations(), obs);
  for (std::size_t i = 0; i < kPts.size(); ++i) {
    EXPECT_EQ(c.x[i], kPts[i].x) << i;
    EXPECT_EQ(c.y[i], kPts[i].y) << i;
    EXPECT_EQ(c.z[i], kPts[i].z) << i;
    if (weight) {
      EXPECT_EQ(c.weight[i], kPts[i].w) << i;
    }
    if (obs) {
      EXPECT_EQ(c.observations[i], kPts[i].obs) << i;
    }
  }
}

/// The bytes of v in little- or big-endian order.
template <typename T>
std::string bin(T v, bool big = false) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big != (std::endian::native == std::endian::big)) std::reverse(b, b + sizeof(T));
  return {b, sizeof(T)};
}

/// A minimal LZF compressor (liblzf format: literal runs of <= 32 bytes, back-references of
/// 3..264 bytes up to 8192 bytes back), exhaustive search; counts what it emitted.
struct Lzf {
  std::string bytes;
  int backrefs = 0;
  int long_backrefs = 0;  // length >= 9: the extra length byte
  int overlapping = 0;    // distance < length: the decoder must copy byte by byte
};

Lzf lzf_compress(std::string_view in) {
  Lzf out;
  std::string lit;
  const auto flush = [&] {
    while (!lit.empty()) {
      const std::size_t n = std::min<std::size_t>(32, lit.size());
      out.bytes += static_cast<char>(n - 1);
      out.bytes.append(lit, 0, n);
      lit.erase(0, n);
    }
  };
  std::size_t i = 0;
  while (i < in.size()) {
    std::size_t best = 0;
    std::size_t best_back = 0;
    for (std::size_t back = 1; back <= std::min<std::size_t>(i, 8192); ++back) {
      std::size_t len = 0;
      while (i + len < in.size() && len < 264 && in[i + len] == in[i + len - back]) ++len;
      if (len > best) {
        best = len;
        best_back = back;
      }
    }
    if (best < 3) {
      lit += in[i++];
      continue;
    }
    flush();
    const std::size_t len = best - 2;
    const std::size_t off = best_back - 1;
    if (len < 7) {
      out.bytes += static_cast<char>((len << 5) | (off >> 8));
    } else {
      out.bytes += static_cast<char>((7 << 5) | (off >> 8));
      out.bytes += static_cast<char>(len - 7);
      ++out.long_backrefs;
    }
    out.bytes += static_cast<char>(off & 0xFF);
    ++out.backrefs;
    if (best_back < best) ++out.overlapping;
    i += best;
  }
  flush();
  return out;
}

template <typename Fn>
std::string error_of(Fn&& fn) {
  return input_error_of(std::forward<Fn>(fn));
}

std::string ply_error(const std::string& bytes) {
  return error_of([&] { (void)parse_ply(bytes, "bad.ply", nullptr); });
}
std::string pcd_error(const std::string& bytes) {
  return error_of([&] { (void)parse_pcd(bytes, "bad.pcd", nullptr); });
}
std::string csv_error(const std::string& text) {
  return error_of([&] { (void)parse_xyz_csv(text, "bad.csv", nullptr); });
}

const std::string kPlyAsciiHead =
    "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
    "property float z\nend_header\n";  // 7 lines

// ---------------------------------------------------------------------------------------------
// PLY

TEST(CloudPly, AsciiWithElementsBeforeAndAfterVertexCommentsAndExtraColumns) {
  std::string text =
      "ply\n"
      "format ascii 1.0\n"
      "comment made by hand\n"
      "obj_info scanner 1\n"
      "element camera 2\n"
      "property float f\n"
      "property list uchar int ids\n"
      "element vertex 5\n"
      "property float x\n"
      "property double y\n"
      "property float z\n"
      "property uchar red\n"
      "property float quality\n"
      "property ushort count\n"
      "element face 1\n"
      "property list uchar int vertex_indices\n"
      "end_header\n"
      "1.5 3 2 4 5\n"
      "2.5 0\n";
  for (const Pt& p : kPts) {
    text += std::to_string(p.x) + " " + std::to_string(p.y) + " " + std::to_string(p.z) + " 200 " +
            std::to_string(p.w) + " " + std::to_string(p.obs) + "\n";
  }
  text += "nan 1 2 0 0.5 1\n3 0 1 2\n";
  CloudReadStats stats;
  const PointCloud c = parse_ply(text, "hand.ply", &stats);
  expect_known(c, true, true);
  EXPECT_EQ(stats.points_read, 4u);
  EXPECT_EQ(stats.non_finite_skipped, 1u);
}

TEST(CloudPly, WriterOutputReadsBackAndIsBinaryLittleEndianRgb) {
  TempDir tmp;
  PointCloud cloud;
  for (const Pt& p : kPts) cloud.push_back({p.x, p.y, p.z});
  const std::vector<std::array<std::uint8_t, 3>> rgb = {
      {255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {10, 20, 30}};
  const auto path = tmp.path() / "walls.ply";
  cloud::write_ply_rgb(path, cloud, rgb);
  EXPECT_FALSE(std::filesystem::exists(tmp.path() / "walls.ply.part"));

  const std::string bytes = slurp(path);
  EXPECT_EQ(bytes.rfind("ply\nformat binary_little_endian 1.0\n", 0), 0u);
  const std::size_t body = bytes.find("end_header\n") + 11;
  ASSERT_EQ(bytes.size(), body + 4 * 15);
  EXPECT_EQ(bytes.substr(body, 4), bin(0.5F));
  EXPECT_EQ(bytes.substr(body + 3 * 15 + 12, 3), std::string("\x0a\x14\x1e"));

  CloudReadStats stats;
  expect_known(read_cloud(path, &stats), false, false);
  EXPECT_EQ(stats.points_read, 4u);

  EXPECT_THROW(cloud::write_ply_rgb(path, cloud, std::span(rgb).first(3)), std::invalid_argument);
  EXPECT_THAT(error_of([&] { cloud::write_ply_rgb(tmp.path() / "no" / "such.ply", cloud, rgb); }),
              HasSubstr("such.ply.part: cannot create"));
}

/// Big-endian, every PLY scalar type between x and y (a wrong size for any of them would shift
/// y, z, confidence and observations), elements before vertex with a list and fixed sizes.
std::string big_endian_ply(std::size_t vertices_written, bool nan_point) {
  std::string s =
      "ply\nformat binary_big_endian 1.0\n"
      "element tag 2\nproperty uchar kind\nproperty list uchar short ids\n"
      "element block 3\nproperty int a\nproperty double b\n"
      "element vertex " +
      std::to_string(kPts.size() + (nan_point ? 1 : 0)) +
      "\n"
      "property double x\n"
      "property char c\nproperty uchar uc\nproperty short s\nproperty ushort us\n"
      "property int i\nproperty uint ui\nproperty float f\n"
      "property int8 i8\nproperty uint8 u8\nproperty int16 i16\nproperty uint16 u16\n"
      "property int32 i32\nproperty uint32 u32\nproperty float64 f64\n"
      "property float32 y\nproperty float z\nproperty double confidence\n"
      "property int observations\n"
      "element face 7\nproperty list uchar int vertex_indices\n"
      "end_header\n";
  const bool be = true;
  // tag: kind 1 with 2 ids, kind 2 with none.
  s += bin<std::uint8_t>(1) + bin<std::uint8_t>(2) + bin<std::int16_t>(-1, be) +
       bin<std::int16_t>(5, be);
  s += bin<std::uint8_t>(2) + bin<std::uint8_t>(0);
  for (int k = 0; k < 3; ++k) s += bin<std::int32_t>(k, be) + bin<double>(k * 0.5, be);
  std::vector<Pt> pts = kPts;
  if (nan_point) pts.insert(pts.begin() + 1, Pt{1.0F, std::nanf(""), 1.0F, 1.0F, 1});
  for (std::size_t k = 0; k < vertices_written && k < pts.size(); ++k) {
    const Pt& p = pts[k];
    s += bin<double>(p.x, be);
    s += bin<std::int8_t>(-7) + bin<std::uint8_t>(250) + bin<std::int16_t>(-300, be) +
         bin<std::uint16_t>(60000, be) + bin<std::int32_t>(-100000, be) +
         bin<std::uint32_t>(4000000000U, be) + bin<float>(1.5F, be);
    s += bin<std::int8_t>(-1) + bin<std::uint8_t>(1) + bin<std::int16_t>(-2, be) +
         bin<std::uint16_t>(2, be) + bin<std::int32_t>(-3, be) + bin<std::uint32_t>(3, be) +
         bin<double>(-4.0, be);
    s += bin<float>(p.y, be) + bin<float>(p.z, be) + bin<double>(p.w, be) +
         bin<std::int32_t>(p.obs, be);
  }
  return s;  // the face element's data is left out: elements after vertex are ignored
}

TEST(CloudPly, BinaryBigEndianEveryScalarTypeAndSkippedElements) {
  CloudReadStats stats;
  expect_known(parse_ply(big_endian_ply(4, false), "be.ply", &stats), true, true);
  EXPECT_EQ(stats.non_finite_skipped, 0u);
  const PointCloud c = parse_ply(big_endian_ply(5, true), "be.ply", &stats);
  expect_known(c, true, true);
  EXPECT_EQ(stats.points_read, 4u);
  EXPECT_EQ(stats.non_finite_skipped, 1u);
}

TEST(CloudPly, BinaryLittleEndianWithFixedSizeElementBeforeVertex) {
  std::string s =
      "ply\r\nformat binary_little_endian 1.0\r\nelement material 2\r\nproperty uchar r\r\n"
      "property float shine\r\nelement vertex 4\r\nproperty float x\r\nproperty float y\r\n"
      "property float z\r\nproperty float weight\r\nproperty uchar obs\r\nend_header\r\n";
  s += std::string(10, '\x7f');
  // One append each: GCC 12 misreads a chain of temporary-string '+' as out of bounds
  // (-Warray-bounds), depending on what the unity build inlines around it.
  for (const Pt& p : kPts) {
    for (const float v : {p.x, p.y, p.z, p.w}) s += bin(v);
    s += bin<std::uint8_t>(static_cast<std::uint8_t>(std::min<int>(p.obs, 255)));
  }
  const PointCloud c = parse_ply(s, "le.ply", nullptr);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c.x[3], 3.25F);
  EXPECT_EQ(c.weight[2], 1.0F);
  EXPECT_EQ(c.observations[3], 255);
  EXPECT_EQ(c.observations[2], 12);
}

TEST(CloudPly, BadInput) {
  EXPECT_THAT(ply_error(""), HasSubstr("bad.ply: empty file"));
  EXPECT_THAT(ply_error("PCD\n"), HasSubstr("bad.ply:1: not a PLY file"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"),
              HasSubstr("bad.ply: truncated header: no end_header line"));
  EXPECT_THAT(ply_error("ply\nformat utf8 1.0\nend_header\n"),
              HasSubstr("bad.ply:2: unknown PLY format 'utf8'"));
  EXPECT_THAT(ply_error("ply\nformat ascii 2.0\nend_header\n"),
              HasSubstr("bad.ply:2: unsupported PLY version '2.0'"));
  EXPECT_THAT(ply_error("ply\nelement vertex 0\nproperty float x\nend_header\n"),
              HasSubstr("bad.ply: header has no format line"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement face 0\nend_header\n"),
              HasSubstr("bad.ply: header has no 'element vertex' line"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
              HasSubstr("bad.ply:3: property line before any element"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty half x\nend_header\n"),
              HasSubstr("bad.ply:4: unknown property type 'half'"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                        "property list uchar float y\nend_header\n"),
              HasSubstr("bad.ply:5: list property 'y' in element vertex is not supported"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement face 1\n"
                        "property list float int idx\nend_header\n"),
              HasSubstr("bad.ply:4: list length type 'float' is not an integer type"));
  EXPECT_THAT(
      ply_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float w\nend_header\n"),
      HasSubstr("bad.ply: no 'z' vertex property (x, y and z are required; found: x, y, w)"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                        "property float x\nend_header\n"),
              HasSubstr("duplicate vertex property 'x'"));
  EXPECT_THAT(
      ply_error("ply\nformat ascii 1.0\nelement vertex 200000000\nend_header\n"),
      HasSubstr("bad.ply:3: element vertex declares 200000000 points, more than the limit"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\n"),
              HasSubstr("bad.ply:3: bad element count '99999999999999999999999'"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nelement vertex -1\n"),
              HasSubstr("bad.ply:3: bad element count '-1'"));
  EXPECT_THAT(ply_error("ply\nformat ascii 1.0\nfoo bar\n"),
              HasSubstr("bad.ply:3: unknown PLY header line 'foo'"));
  // Ascii body: short, bad numbers, too few rows (with the line).
  EXPECT_THAT(ply_error(kPlyAsciiHead + "1 2 3\n4 5\n"),
              HasSubstr("bad.ply:9: expected 3 vertex values, found 2"));
  EXPECT_THAT(ply_error(kPlyAsciiHead + "1 2 3\n4 five 6\n"),
              HasSubstr("bad.ply:9: bad number 'five' for property 'y'"));
  EXPECT_THAT(ply_error(kPlyAsciiHead + "1 2 3\n"),
              HasSubstr("bad.ply:8: truncated: element vertex declares 2 points, found 1"));
  // Binary body: fewer bytes than the header says, in the vertex data and before it.
  std::string be = big_endian_ply(4, false);
  EXPECT_THAT(
      ply_error(be.substr(0, be.size() - 1)),
      HasSubstr("bad.ply: truncated: 4 vertices of 68 bytes need 272 bytes, only 271 follow"));
  const std::size_t body = be.find("end_header\n") + 11;
  EXPECT_THAT(
      ply_error(be.substr(0, body + 3)),
      HasSubstr("bad.ply: truncated: element 'tag' declares 2 entries, data ends in entry 0"));
  EXPECT_THAT(ply_error(be.substr(0, body + 8)),
              HasSubstr("bad.ply: truncated: element 'block' declares 3 entries"));
  // Optional columns must hold sane values on kept points.
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nproperty float weight\nproperty float observations\nend_header\n";
  EXPECT_THAT(ply_error(head + "1 2 3 inf 1\n"),
              HasSubstr("bad.ply:10: weight is not a finite float"));
  EXPECT_THAT(ply_error(head + "1 2 3 1 -1\n"),
              HasSubstr("bad.ply:10: observation count must be a non-negative integer"));
  EXPECT_THAT(ply_error(head + "1 2 3 1 1.5\n"),
              HasSubstr("bad.ply:10: observation count must be a non-negative integer"));
  EXPECT_EQ(parse_ply(head + "1 2 3 1 70000\n", "sat.ply").observations.at(0), 65535);
}

TEST(CloudPly, CoordinatesBeyondFloatRangeAreSkippedAsNonFinite) {
  CloudReadStats stats;
  const PointCloud c = parse_ply(kPlyAsciiHead + "1e300 0 0\n1 -inf 2\n", "big.ply", &stats);
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(stats.non_finite_skipped, 2u);
}

// ---------------------------------------------------------------------------------------------
// PCD

TEST(CloudPcd, AsciiWithCountFieldsPaddingAndNan) {
  std::string text =
      "# .PCD v0.7 - Point Cloud Data file format\n"
      "VERSION 0.7\n"
      "FIELDS x y z normal confidence _ obs\n"
      "SIZE 4 4 4 4 4 1 2\n"
      "TYPE F F F F F U U\n"
      "COUNT 1 1 1 3 1 2 1\n"
      "WIDTH 5\n"
      "HEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\n"
      "POINTS 5\n"
      "DATA ascii\n";
  for (const Pt& p : kPts) {
    text += std::to_string(p.x) + " " + std::to_string(p.y) + " " + std::to_string(p.z) +
            " 0 0 1 " + std::to_string(p.w) + " 0 0 " + std::to_string(p.obs) + "\n";
    if (&p == &kPts[1]) text += "nan nan nan nan nan nan nan 0 0 0\n";
  }
  CloudReadStats stats;
  expect_known(parse_pcd(text, "a.pcd", &stats), true, true);
  EXPECT_EQ(stats.points_read, 4u);
  EXPECT_EQ(stats.non_finite_skipped, 1u);
}

/// PCD binary rows: x F8, padding U1 x3, y F4, normal F4 x3, z I4 (integral), I8 and U8
/// fields, weight F4 ("quality"), obs U2 ("count").
std::string pcd_binary(std::size_t rows_written, const std::string& version = "0.6") {
  std::string s = "VERSION " + version +
                  "\nFIELDS x _ y normal z big ubig quality count\n"
                  "SIZE 8 1 4 4 4 8 8 4 2\nTYPE F U F F I I U F U\nCOUNT 1 3 1 3 1 1 1 1 1\n"
                  "WIDTH 2\nHEIGHT 2\nPOINTS 4\nDATA binary\n";
  const std::array<std::int32_t, 4> z = {-3, 7, 0, 2147483647};
  for (std::size_t k = 0; k < rows_written; ++k) {
    const Pt& p = kPts[k];
    s += bin<double>(p.x) + std::string(3, '\xEE') + bin(p.y) + bin(1.0F) + bin(0.0F) + bin(0.0F) +
         bin<std::int32_t>(z[k]) + bin<std::int64_t>(-5) + bin<std::uint64_t>(9) + bin(p.w) +
         bin<std::uint16_t>(p.obs);
  }
  return s;
}

TEST(CloudPcd, BinaryVersion06AllTypes) {
  const PointCloud c = parse_pcd(pcd_binary(4), "b.pcd", nullptr);
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(c.x[1], 0.0625F);
  EXPECT_EQ(c.y[3], -0.5F);
  EXPECT_EQ(c.z[0], -3.0F);
  EXPECT_EQ(c.z[3], 2147483647.0F);
  EXPECT_EQ(c.weight[2], 1.0F);
  EXPECT_EQ(c.observations[3], 700);
}

/// A binary_compressed PCD of `w` x `h` points (a grid, so LZF finds long back-references),
/// with an extra F4 field and a U1 padding field of COUNT 3; fields stored column-wise.
std::string pcd_compressed(int w, int h, Lzf* lzf_out = nullptr) {
  const int n = w * h;
  std::string cols[6];
  for (int i = 0; i < n; ++i) {
    cols[0] += bin(0.25F * static_cast<float>(i % w));
    cols[1] += bin(-0.5F * static_cast<float>(i / w));
    cols[2] += bin(i == 5 ? std::numeric_limits<float>::quiet_NaN() : 1.5F);
    cols[3] += bin(0.0F);
    cols[4] += std::string("\x01\x02\x03", 3);
    cols[5] += bin<std::uint16_t>(static_cast<std::uint16_t>(i % 3));
  }
  std::string raw;
  for (const std::string& c : cols) raw += c;
  Lzf lzf = lzf_compress(raw);
  std::string s =
      "# made by test_cloud_io\nVERSION .7\nFIELDS x y z intensity _ obs\n"
      "SIZE 4 4 4 4 1 2\nTYPE F F F F U U\nCOUNT 1 1 1 1 3 1\nWIDTH " +
      std::to_string(w) + "\nHEIGHT " + std::to_string(h) + "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
      std::to_string(n) + "\nDATA binary_compressed\n";
  s += bin<std::uint32_t>(static_cast<std::uint32_t>(lzf.bytes.size())) +
       bin<std::uint32_t>(static_cast<std::uint32_t>(raw.size())) + lzf.bytes;
  if (lzf_out != nullptr) *lzf_out = lzf;
  return s;
}

TEST(CloudPcd, BinaryCompressedColumnWiseWithRealBackReferences) {
  Lzf lzf;
  const std::string s = pcd_compressed(20, 3, &lzf);
  EXPECT_GT(lzf.backrefs, 5);
  EXPECT_GT(lzf.long_backrefs, 0);
  EXPECT_GT(lzf.overlapping, 0);
  EXPECT_LT(lzf.bytes.size(), 60u * 21 / 2);
  CloudReadStats stats;
  const PointCloud c = parse_pcd(s, "c.pcd", &stats);
  EXPECT_EQ(stats.points_read, 59u);
  EXPECT_EQ(stats.non_finite_skipped, 1u);
  ASSERT_EQ(c.size(), 59u);
  ASSERT_TRUE(c.has_observations());
  EXPECT_FALSE(c.has_weight());
  // Point 7 of the file is c[6] (point 5 was skipped).
  EXPECT_EQ(c.x[6], 0.25F * 7);
  EXPECT_EQ(c.y[6], 0.0F);
  EXPECT_EQ(c.z[6], 1.5F);
  EXPECT_EQ(c.observations[6], 7 % 3);
  EXPECT_EQ(c.x.back(), 0.25F * 19);
  EXPECT_EQ(c.y.back(), -1.0F);
  EXPECT_EQ(c.observations.back(), 59 % 3);
}

TEST(CloudPcd, ReadsThePclReferenceCloud) {
  CloudReadStats stats;
  const PointCloud c =
      read_cloud(std::filesystem::path(WALLAR_TEST_DATA) / "pcl" / "sac_plane_test.pcd", &stats);
  EXPECT_EQ(c.size(), 3283u);
  EXPECT_EQ(stats.points_read, 3283u);
  EXPECT_EQ(stats.non_finite_skipped, 0u);  // its NaNs are in normals only
  EXPECT_FALSE(c.has_weight());
  EXPECT_FALSE(c.has_observations());
  ASSERT_FALSE(c.empty());
  EXPECT_EQ(c.x[0], 1.068F);
  EXPECT_EQ(c.y[0], 0.094720997F);
  EXPECT_EQ(c.z[0], -0.016231F);
  EXPECT_EQ(c.x.back(), 1.2798001F);
  EXPECT_EQ(c.y.back(), -0.41073F);
  EXPECT_EQ(c.z.back(), -0.18623F);
}

TEST(CloudPcd, BadInput) {
  const std::string head3 =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
      "POINTS 2\n";  // 8 lines
  EXPECT_THAT(pcd_error(""), HasSubstr("bad.pcd: empty file"));
  EXPECT_THAT(pcd_error("VERSION 0.7\n"), HasSubstr("bad.pcd: truncated header: no DATA line"));
  EXPECT_THAT(pcd_error("VERSION 0.5\n"), HasSubstr("bad.pcd:1: unsupported PCD version '0.5'"));
  EXPECT_THAT(pcd_error("ply\n"), HasSubstr("bad.pcd:1: unknown PCD header line 'ply'"));
  EXPECT_THAT(pcd_error(head3 + "DATA binary_lz4\n"),
              HasSubstr("bad.pcd:9: unknown DATA type 'binary_lz4'"));
  EXPECT_THAT(pcd_error("VERSION 0.7\nDATA ascii\n"),
              HasSubstr("bad.pcd:2: header has no FIELDS line"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n"),
              HasSubstr("bad.pcd:2: SIZE has 2 entries, FIELDS has 3"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F\nWIDTH 1\nDATA ascii\n"),
              HasSubstr("bad.pcd:3: TYPE has 2 entries, FIELDS has 3"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nWIDTH 1\nDATA ascii\n"),
              HasSubstr("bad.pcd:3: field 'z' has unsupported TYPE/SIZE F2"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nWIDTH 1\nDATA ascii\n"),
              HasSubstr("field 'z' has unsupported TYPE/SIZE Q4"));
  EXPECT_THAT(pcd_error("FIELDS x y rgb\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n"),
              HasSubstr("bad.pcd:1: no 'z' field (x, y and z are required; found: x, y, rgb)"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 3 1\nWIDTH 1\nDATA ascii\n"),
              HasSubstr("bad.pcd:1: field 'y' has COUNT 3 (x, y and z must have COUNT 1)"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 0 1\nWIDTH 1\nDATA ascii\n"),
              HasSubstr("bad.pcd:4: field 'y' has COUNT 0"));
  EXPECT_THAT(pcd_error("FIELDS x y z n\nSIZE 4 4 4 8\nTYPE F F F F\n"
                        "COUNT 1 1 1 4611686018427387904\nWIDTH 1\nDATA binary\n"),
              HasSubstr("bad.pcd:4: field sizes overflow"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA ascii\n"),
              HasSubstr("bad.pcd:4: header has no WIDTH line"));
  EXPECT_THAT(
      pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nHEIGHT 2\nPOINTS 5\nDATA ascii\n"),
      HasSubstr("bad.pcd:6: POINTS 5 is not WIDTH x HEIGHT = 6"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4294967296\nHEIGHT "
                        "4294967296\nDATA ascii\n"),
              HasSubstr("bad.pcd:6: WIDTH x HEIGHT overflows"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 100000001\nDATA binary\n"),
              HasSubstr("bad.pcd:5: declares 100000001 points, more than the limit of 100000000"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH -2\nDATA ascii\n"),
              HasSubstr("bad.pcd:4: WIDTH must be one non-negative integer"));
  EXPECT_THAT(pcd_error("FIELDS x y z\nSIZE 4 4 4\nVIEWPOINT 0 0 0\n"),
              HasSubstr("bad.pcd:3: VIEWPOINT must have 7 numbers"));
  // Ascii rows.
  EXPECT_THAT(pcd_error(head3 + "DATA ascii\n1 2 3\n"),
              HasSubstr("bad.pcd:10: truncated: POINTS is 2, found 1 rows"));
  EXPECT_THAT(pcd_error(head3 + "DATA ascii\n1 2 3\n1 2\n"),
              HasSubstr("bad.pcd:11: expected 3 values, found 2"));
  EXPECT_THAT(pcd_error(head3 + "DATA ascii\n1 2 3\n1 2 3x\n"),
              HasSubstr("bad.pcd:11: bad number '3x' for field 'z'"));
  // Binary rows.
  const std::string b = pcd_binary(4);
  EXPECT_THAT(
      pcd_error(b.substr(0, b.size() - 2)),
      HasSubstr("bad.pcd: truncated: 4 points of 53 bytes need 212 bytes, only 210 follow"));
  EXPECT_THAT(pcd_error(pcd_binary(0)), HasSubstr("only 0 follow"));
  // No points: no data needed, in any encoding (size words optional when compressed).
  for (const char* data : {"ascii", "binary", "binary_compressed"}) {
    EXPECT_TRUE(
        parse_pcd("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 0\nDATA " + std::string(data) + "\n",
                  "none.pcd")
            .empty());
  }
}

TEST(CloudPcd, BadCompressedData) {
  const std::string good = pcd_compressed(4, 2);
  const std::size_t body = good.find("binary_compressed\n") + 18;
  const std::string head = good.substr(0, body);
  const std::string lzf = good.substr(body + 8);
  const std::uint32_t raw = 8 * 21;  // x y z intensity F4, _ 3 x U1, obs U2
  const auto with = [&](std::uint32_t csize, std::uint32_t usize, const std::string& data) {
    return head + bin(csize) + bin(usize) + data;
  };
  EXPECT_THAT(pcd_error(head + "abc"),
              HasSubstr("bad.pcd: truncated: binary_compressed data has no size words"));
  EXPECT_THAT(
      pcd_error(with(static_cast<std::uint32_t>(lzf.size() + 1), raw, lzf)),
      HasSubstr("truncated: " + std::to_string(lzf.size() + 1) + " compressed bytes declared"));
  EXPECT_THAT(
      pcd_error(with(static_cast<std::uint32_t>(lzf.size()), raw + 4, lzf)),
      HasSubstr(
          "bad.pcd: binary_compressed: uncompressed size 172 is not POINTS x row size = 168"));
  // Corrupt streams: cut short, a back-reference before the start, an impossible ratio.
  EXPECT_THAT(pcd_error(with(static_cast<std::uint32_t>(lzf.size() - 1), raw, lzf)),
              HasSubstr("bad.pcd: corrupt LZF data:"));
  EXPECT_THAT(pcd_error(with(2, raw, std::string("\x20\x00", 2))), HasSubstr("corrupt LZF data:"));
  EXPECT_THAT(pcd_error(with(1, raw, "\x1f")),
              HasSubstr("corrupt LZF data: declared size 168 is impossible"));
  // A flipped byte anywhere in the stream: still decodes, or a clean error.
  for (std::size_t i = 0; i < lzf.size(); ++i) {
    std::string bad = lzf;
    bad[i] = static_cast<char>(bad[i] ^ 0xA5);
    try {
      (void)parse_pcd(with(static_cast<std::uint32_t>(bad.size()), raw, bad), "flip.pcd", nullptr);
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("flip.pcd: ")) << i;
    }
  }
}

TEST(CloudLzf, HandCraftedStreamsAndCorruption) {
  const std::string n = "lzf";
  // "abc" literal, then 6 bytes from 3 back: "abcabcabc".
  EXPECT_EQ(cloud::lzf_decompress(std::string("\x02"
                                              "abc"
                                              "\x80\x02",
                                              6),
                                  9, n),
            "abcabcabc");
  // "a" then a long back-reference 1 back of 7 + 3 + 2 = 12 bytes (overlapping run).
  EXPECT_EQ(cloud::lzf_decompress(std::string("\x00"
                                              "a"
                                              "\xe0\x03\x00",
                                              5),
                                  13, n),
            std::string(13, 'a'));
  EXPECT_THAT(error_of([&] { (void)cloud::lzf_decompress(std::string("\x20\x00", 2), 3, n); }),
              HasSubstr("lzf: corrupt LZF data: back-reference to 1 bytes back at output byte 0"));
  EXPECT_THAT(error_of([&] {
                (void)cloud::lzf_decompress(
                    "\x05"
                    "a",
                    6, n);
              }),
              HasSubstr("literal run past the end of the input"));
  EXPECT_THAT(error_of([&] {
                (void)cloud::lzf_decompress(
                    "\x02"
                    "abc",
                    2, n);
              }),
              HasSubstr("output longer than the declared 2 bytes"));
  EXPECT_THAT(error_of([&] {
                (void)cloud::lzf_decompress(std::string("\x02"
                                                        "abc"
                                                        "\x80\x02",
                                                        6),
                                            12, n);
              }),
              HasSubstr("decompresses to 9 bytes, the header says 12"));
  EXPECT_THAT(error_of([&] {
                (void)cloud::lzf_decompress(std::string("\x00"
                                                        "a"
                                                        "\x20",
                                                        3),
                                            4, n);
              }),
              HasSubstr("back-reference cut off"));
  EXPECT_THAT(error_of([&] {
                (void)cloud::lzf_decompress(std::string("\x00"
                                                        "a"
                                                        "\xe0",
                                                        3),
                                            12, n);
              }),
              HasSubstr("back-reference cut off"));
  EXPECT_THAT(error_of([&] { (void)cloud::lzf_decompress("ab", 177, n); }),
              HasSubstr("declared size 177 is impossible for 2 compressed bytes"));
}

// ---------------------------------------------------------------------------------------------
// CSV / XYZ

TEST(CloudCsv, CommaSeparatedWithNamedReorderedColumns) {
  std::string text = "# exported points\nid,Z,Y,X,confidence,obs,label\n";
  int id = 0;
  for (const Pt& p : kPts) {
    text += std::to_string(id++) + ", " + std::to_string(p.z) + "," + std::to_string(p.y) + "," +
            std::to_string(p.x) + "," + std::to_string(p.w) + "," + std::to_string(p.obs) +
            ",wall\r\n";
  }
  text += "9,1,NaN,2,1,1,floor\n\n";
  CloudReadStats stats;
  expect_known(parse_xyz_csv(text, "p.csv", &stats), true, true);
  EXPECT_EQ(stats.non_finite_skipped, 1u);
}

TEST(CloudCsv, WhitespaceXyzWithoutHeaderAndCloudCompareHeader) {
  TempDir tmp;
  std::string xyz = "# x y z r g b\n";
  for (const Pt& p : kPts) {
    xyz += std::to_string(p.x) + "\t" + std::to_string(p.y) + "  " + std::to_string(p.z) +
           " 255 0 0\n";
  }
  spit(tmp.path() / "p.XYZ", xyz);
  expect_known(read_cloud(tmp.path() / "p.XYZ"), false, false);

  std::string cc = "//X,Y,Z,Quality\n";
  for (const Pt& p : kPts) {
    cc += std::to_string(p.x) + "," + std::to_string(p.y) + "," + std::to_string(p.z) + "," +
          std::to_string(p.w) + "\n";
  }
  spit(tmp.path() / "p.txt", cc);
  expect_known(read_cloud(tmp.path() / "p.txt"), true, false);
  // Spreadsheet exports may start with a UTF-8 byte order mark.
  EXPECT_EQ(parse_xyz_csv("\xEF\xBB\xBFx,y,z\n1,2,3\n", "bom.csv").size(), 1u);
}

TEST(CloudCsv, BadInput) {
  EXPECT_THAT(csv_error(""), HasSubstr("bad.csv: empty file"));
  EXPECT_THAT(csv_error("# nothing\n\n"),
              HasSubstr("bad.csv: no data (only blank or comment lines)"));
  EXPECT_THAT(csv_error("1,2\n"),
              HasSubstr("bad.csv:1: expected at least 3 columns (x, y, z), found 2"));
  EXPECT_THAT(csv_error("1,2,3\n4,5\n"), HasSubstr("bad.csv:2: expected 3 fields, found 2"));
  EXPECT_THAT(csv_error("1 2 3\n4 5 6 7\n"), HasSubstr("bad.csv:2: expected 3 fields, found 4"));
  EXPECT_THAT(csv_error("1,2,3\n# c\n4,5,6e\n"),
              HasSubstr("bad.csv:3: bad number '6e' in column 3 (z)"));
  EXPECT_THAT(csv_error("a,b,c\n1,2,3\n"),
              HasSubstr("bad.csv:1: no 'x' column (x, y and z are required; found: a, b, c)"));
  EXPECT_THAT(csv_error("x,y,z,w\n1,2,,4\n"),
              HasSubstr("bad.csv:2: bad number '' in column 3 ('z')"));
  EXPECT_THAT(csv_error("x,y,z,weight\n1,2,3,nan\n"),
              HasSubstr("bad.csv:2: weight is not a finite float"));
  EXPECT_THAT(csv_error(std::string("1,2,3\n4,5,\0", 11)), HasSubstr("bad.csv:2: bad number"));
}

// ---------------------------------------------------------------------------------------------
// read_cloud and hostile input

TEST(CloudRead, DispatchesByExtensionAndNamesTheFile) {
  TempDir tmp;
  spit(tmp.path() / "a.PLY", kPlyAsciiHead + "1 2 3\n4 5 6\n");
  spit(tmp.path() / "b.pcd", pcd_binary(4, "0.7"));
  EXPECT_EQ(read_cloud(tmp.path() / "a.PLY").size(), 2u);
  EXPECT_EQ(read_cloud(tmp.path() / "b.pcd").size(), 4u);
  spit(tmp.path() / "c.obj", "v 1 2 3\n");
  EXPECT_THAT(
      error_of([&] { (void)read_cloud(tmp.path() / "c.obj"); }),
      HasSubstr(
          "c.obj: unknown point cloud extension '.obj' (want .ply, .pcd, .csv, .txt or .xyz)"));
  EXPECT_THAT(error_of([&] { (void)read_cloud(tmp.path() / "missing.ply"); }),
              HasSubstr("missing.ply: no such file"));
  spit(tmp.path() / "empty.pcd", "");
  EXPECT_THAT(error_of([&] { (void)read_cloud(tmp.path() / "empty.pcd"); }),
              HasSubstr((tmp.path() / "empty.pcd").string() + ": empty file"));
  // A PLY named .pcd is reported as what it is not.
  spit(tmp.path() / "d.pcd", kPlyAsciiHead);
  EXPECT_THAT(error_of([&] { (void)read_cloud(tmp.path() / "d.pcd"); }),
              HasSubstr("d.pcd:1: unknown PCD header line 'ply'"));
}

/// Every prefix and many random byte changes of valid files, through every parser: the only
/// outcomes allowed are a cloud or an InputError (ASan/UBSan builds check the memory side).
TEST(CloudRead, TruncatedAndMutatedInputOnlyEverGivesInputError) {
  const std::vector<std::string> seeds = {big_endian_ply(5, true), pcd_binary(4),
                                          pcd_compressed(6, 2), kPlyAsciiHead + "1 2 3\n4 5 6\n",
                                          "x,y,z,obs\n1,2,3,4\n"};
  std::mt19937 rng(1234);
  std::size_t runs = 0;
  const auto run = [&](const std::string& bytes) {
    for (int f = 0; f < 3; ++f) {
      try {
        const PointCloud c = f == 0   ? parse_ply(bytes, "f", nullptr)
                             : f == 1 ? parse_pcd(bytes, "f", nullptr)
                                      : parse_xyz_csv(bytes, "f", nullptr);
        EXPECT_TRUE(c.consistent());
      } catch (const InputError&) {
      }
      ++runs;
    }
  };
  for (const std::string& s : seeds) {
    for (std::size_t len = 0; len <= s.size(); ++len) run(s.substr(0, len));
    for (int k = 0; k < 300; ++k) {
      std::string m = s;
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits; ++e) {
        m[rng() % m.size()] = static_cast<char>(rng() & 0xFF);
      }
      run(m);
    }
  }
  EXPECT_GT(runs, 3000u);
}

}  // namespace
}  // namespace wallar::test
