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
bool is_segment_name(const std::string& name) {
  return name.size() == 6 && name.find_first_not_of("0123456789") == std::string::npos;
}
}  // namespace

RotatingEurocWriter::RotatingEurocWriter(fs::path root, RigCalibration rig, RotationOptions options)
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
                              "/); refusing to rotate over them");
      }
    }
  }
  start_segment();
}

void RotatingEurocWriter::start_segment() {
  char name[16];
  std::snprintf(name, sizeof name, "%06llu",
                static_cast<unsigned long long>(counters_.segments_started + 1));  // NOLINT
  current_dir_ = root_ / name;
  current_ = std::make_unique<EurocWriter>(current_dir_, rig_, options_.writer);
  ++counters_.segments_started;
}

void RotatingEurocWriter::rotate_if_full() {
  if (options_.segment_bytes > 0 && current_->bytes_written() >= options_.segment_bytes) {
    current_->close();
    closed_.push_back({current_dir_, current_->bytes_written()});
    closed_bytes_ += current_->bytes_written();
    current_.reset();
    start_segment();
  }
  enforce_cap();
}

void RotatingEurocWriter::enforce_cap() {
  if (options_.max_total_bytes == 0) return;
  while (!closed_.empty() && closed_bytes_ + current_->bytes_written() > options_.max_total_bytes) {
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

void RotatingEurocWriter::write_imu(const ImuSample& sample) {
  rotate_if_full();
  current_->write_imu(sample);
}

void RotatingEurocWriter::write_camera(int cam, const CameraFrame& frame) {
  if (cam == 0) rotate_if_full();  // a pair's right image stays with its left one
  current_->write_camera(cam, frame);
}

void RotatingEurocWriter::close() { current_->close(); }

std::deque<fs::path> RotatingEurocWriter::segments() const {
  std::deque<fs::path> out;
  for (const Closed& c : closed_) out.push_back(c.dir);
  out.push_back(current_dir_);
  return out;
}

std::uint64_t RotatingEurocWriter::total_bytes() const {
  return closed_bytes_ + current_->bytes_written();
}

}  // namespace wallar::recording
