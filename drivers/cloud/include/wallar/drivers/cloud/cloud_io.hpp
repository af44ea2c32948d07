// SPDX-License-Identifier: Apache-2.0
/// @file cloud_io.hpp
/// @brief Strict, dependency-free point-cloud readers (PLY, PCD, CSV/XYZ) and a PLY writer,
/// for `wallar walls INPUT`.
///
/// Readers fill a wallar::PointCloud (SoA floats). Optional per-point columns are kept when
/// the file has them: a quality column named "weight", "confidence" or "quality" (case
/// insensitive; the first such column wins) goes to PointCloud::weight, an observation count
/// named "observations", "obs" or "count" to PointCloud::observations (a non-negative integer,
/// saturated at 65535). Points whose x, y or z is NaN or infinite (also after narrowing to
/// float) are skipped and counted; a non-finite weight or a bad count on a kept point is an
/// error.
///
/// Every problem with the input is a wallar::InputError with one line "NAME:LINE: what" (text
/// parts of a file) or "NAME: what" (binary parts). Hostile input never reads out of bounds and
/// never allocates much more than the input's size; point counts are capped at kMaxCloudPoints.
/// Having few points is not an error here (callers decide how many they need).
///
/// Formats:
///  - PLY 1.0: ascii, binary_little_endian, binary_big_endian. Every PLY scalar type
///    (char/uchar/short/ushort/int/uint/float/double and int8..float64). Elements before
///    "vertex" are skipped (in binary also those with list properties, sized instance by
///    instance); elements after it are ignored. A list property in "vertex" is an error.
///  - PCD 0.6/0.7: DATA ascii, binary and binary_compressed (LZF, column-wise). Types F4/F8,
///    I1/I2/I4/I8, U1/U2/U4/U8; fields with COUNT > 1 (padding "_", normals...) are skipped.
///  - CSV/XYZ text: comma or whitespace separated (decided by the first data line), '#'
///    comments, optional header line naming the columns (a leading "//" as written by
///    CloudCompare is accepted); without a header the first three columns are x, y, z.
///
/// Threading: pure functions.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "wallar/core/point_cloud.hpp"

namespace wallar::cloud {

/// The largest number of points a file may declare (larger is rejected as bad input).
inline constexpr std::size_t kMaxCloudPoints = 100'000'000;

struct CloudReadStats {
  std::size_t points_read = 0;         //!< points kept in the cloud
  std::size_t non_finite_skipped = 0;  //!< points dropped for a NaN/Inf coordinate
};

/// Reads a cloud, choosing the parser by extension (case insensitive): .ply, .pcd, or
/// .csv/.txt/.xyz. Throws InputError for a missing file, an unknown extension or bad content.
PointCloud read_cloud(const std::filesystem::path& path, CloudReadStats* stats = nullptr);

/// The parsers behind read_cloud; `name` is used in error messages. `stats` may be null.
PointCloud parse_ply(std::string_view bytes, const std::string& name,
                     CloudReadStats* stats = nullptr);
PointCloud parse_pcd(std::string_view bytes, const std::string& name,
                     CloudReadStats* stats = nullptr);
PointCloud parse_xyz_csv(std::string_view text, const std::string& name,
                         CloudReadStats* stats = nullptr);

/// LZF decompression (liblzf format, as in PCD binary_compressed) of `in` into exactly
/// `out_size` bytes; throws InputError "NAME: ..." on any corruption (bad back-reference,
/// overrun, wrong decompressed size).
std::string lzf_decompress(std::string_view in, std::size_t out_size, const std::string& name);

/// Writes a binary little-endian PLY: float x, y, z and uchar red, green, blue per point.
/// rgb must have one entry per point (std::invalid_argument otherwise); I/O failures throw
/// InputError naming the path. The file is written to PATH.part and renamed into place.
void write_ply_rgb(const std::filesystem::path& path, const PointCloud& cloud,
                   std::span<const std::array<std::uint8_t, 3>> rgb);

/// Writes a sparse map as binary little-endian PLY: float x, y, z, float sigma (position
/// uncertainty [m], 0 when `sigma_m` is empty) and ushort observations per point, which
/// read_cloud reads back as the observation count. Atomic like write_ply_rgb.
void write_ply_map(const std::filesystem::path& path, const PointCloud& cloud,
                   std::span<const float> sigma_m);

}  // namespace wallar::cloud
