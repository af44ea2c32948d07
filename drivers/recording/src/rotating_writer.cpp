// SPDX-License-Identifier: Apache-2.0
/// @file rotating_writer.cpp
/// @brief Segments of a size, the oldest deleted above a total.
#include "wallar/drivers/recording/rotating_writer.hpp"

#include <cstdio>
#include <system_error>
#include <utility>

#include "wallar/core/error.hpp"

namespace wallar::recording {
namespace fs = std::filesystem;

namespace {
// 000001 (a EuRoC folder) or 000001.mcap.
bool is_segment_name(const std::string& name) {
  const std::string stem = name.size() == 11 && name.ends_with(".mcap") ? name.substr(0, 6) : name;
  return stem.size() == 6 && stem.find_first_not_of("0123456789") == std::string::npos;
}
}  // namespace

RotationOptions rotation_from_mib(double segment_mib, double max_mib, const std::string& what) {
  if (max_mib > 0.0 && segment_mib <= 0.0) {
    throw InputError(what +
                     ": --max-mb needs --segment-mb (the size of the segments that are deleted, "
                     "oldest first, to stay under it)");
  }
  if (max_mib > 0.0 && max_mib < 2.0 * segment_mib) {
    throw InputError(what + ": --max-mb " + std::to_string(max_mib) +
                     " must hold at least two segments of --segment-mb " +
                     std::to_string(segment_mib));
  }
  const auto bytes = [](double mib) { return static_cast<std::uint64_t>(mib * 1024.0 * 1024.0); };
  RotationOptions o;
  o.segment_bytes = bytes(segment_mib);
  o.max_total_bytes = bytes(max_mib);
  return o;
}

RotatingWriter::RotatingWriter(fs::path root, RigCalibration rig, RotationOptions options)
    : root_(std::move(root)), rig_(std::move(rig)), options_(options) {
  std::error_code ec;
  if (fs::exists(root_ / "mav0", ec)) {
    throw_input_error(root_.string(), 0,
                      "already holds a recording (mav0/); refusing to overwrite it");
  }
  if (fs::is_directory(root_, ec)) {
    for (const fs::directory_entry& e : fs::directory_iterator(root_, ec)) {
      if (is_segment_name(e.path().filename().string())) {
        throw_input_error(root_.string(), 0,
                          "already holds recording segments (" + e.path().filename().string() +
                              "); refusing to rotate over them");
      }
    }
  }
  start_segment();
}

void RotatingWriter::start_segment() {
  char name[16];
  std::snprintf(name, sizeof name, "%06llu",
                static_cast<unsigned long long>(counters_.segments_started + 1));  // NOLINT
  if (options_.format == RotationOptions::Format::kMcap) {
    std::error_code ec;
    fs::create_directories(root_, ec);
    if (ec) throw_input_error(root_.string(), 0, "cannot create the folder: " + ec.message());
    current_dir_ = root_ / (std::string(name) + ".mcap");
    mcap_ = std::make_unique<McapRecordingWriter>(current_dir_, rig_, options_.mcap);
  } else {
    current_dir_ = root_ / name;
    euroc_ = std::make_unique<EurocWriter>(current_dir_, rig_, options_.writer);
  }
  ++counters_.segments_started;
}

RecordingWriter& RotatingWriter::current() {
  if (mcap_) return *mcap_;
  return *euroc_;
}

std::uint64_t RotatingWriter::current_bytes() const {
  return mcap_ ? mcap_->bytes_written() : euroc_->bytes_written();
}

void RotatingWriter::rotate_if_full() {
  if (options_.segment_bytes > 0 && current_bytes() >= options_.segment_bytes) {
    current().close();
    const std::uint64_t bytes = current_bytes();  // an MCAP file's summary and footer too
    closed_.push_back({current_dir_, bytes});
    closed_bytes_ += bytes;
    euroc_.reset();
    mcap_.reset();
    start_segment();
  }
  enforce_cap();
}

void RotatingWriter::enforce_cap() {
  if (options_.max_total_bytes == 0) return;
  while (!closed_.empty() && closed_bytes_ + current_bytes() > options_.max_total_bytes) {
    const Closed oldest = closed_.front();
    closed_.pop_front();
    closed_bytes_ -= oldest.bytes;
    std::error_code ec;
    fs::remove_all(oldest.dir, ec);
    if (ec) {
      ++counters_.delete_errors;
    } else {
      ++counters_.segments_deleted;
      counters_.bytes_deleted += oldest.bytes;
    }
  }
}

void RotatingWriter::write_imu(const ImuSample& sample) {
  rotate_if_full();
  current().write_imu(sample);
}

void RotatingWriter::write_camera(int cam, const CameraFrame& frame) {
  if (cam == 0) rotate_if_full();  // a pair's right image stays with its left one
  current().write_camera(cam, frame);
}

void RotatingWriter::close() { current().close(); }

std::deque<fs::path> RotatingWriter::segments() const {
  std::deque<fs::path> out;
  for (const Closed& c : closed_) out.push_back(c.dir);
  out.push_back(current_dir_);
  return out;
}

std::uint64_t RotatingWriter::total_bytes() const { return closed_bytes_ + current_bytes(); }

}  // namespace wallar::recording
