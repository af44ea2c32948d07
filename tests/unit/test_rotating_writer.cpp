// SPDX-License-Identifier: Apache-2.0
/// @file test_rotating_writer.cpp
/// @brief A rotating recording: segments of a size, each a whole EuRoC recording, the oldest
/// deleted under the cap, the kept ones the stream's unbroken tail.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <vector>

#include "test_support.hpp"
#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"
#include "wallar/drivers/recording/rotating_writer.hpp"

namespace wallar::test {
namespace {
namespace fs = std::filesystem;

TEST(RotatingWriter, SegmentsOfASizeTheOldestDeletedUnderTheCapTheRestTheStreamsTail) {
  const fs::path root = fs::temp_directory_path() / "wallar_rotating";
  fs::remove_all(root);
  // One pair with its 10 IMU rows is about 1.5 kB here: ~2 pairs a segment, ~4 under the cap.
  recording::RotationOptions o;
  o.segment_bytes = 3000;
  o.max_total_bytes = 7000;
  constexpr int kPairs = 30;
  std::uint64_t kept_bytes = 0;
  {
    recording::RotatingWriter w(root, small_rig(), o);
    write_small_stream(w, kPairs, 11);
    const recording::RotationCounters& c = w.counters();
    EXPECT_GE(c.segments_started, 8u);
    EXPECT_GE(c.segments_deleted, 4u);
    EXPECT_EQ(c.delete_errors, 0u);
    EXPECT_EQ(w.segments().size(), c.segments_started - c.segments_deleted);
    EXPECT_LE(w.total_bytes(), o.max_total_bytes + o.segment_bytes);
    kept_bytes = w.total_bytes();
    EXPECT_GT(kept_bytes, o.max_total_bytes - o.segment_bytes - 1600);
  }
  // On disk: the kept segments only, numbered on from the deleted ones, each a recording.
  std::vector<fs::path> dirs;
  for (const fs::directory_entry& e : fs::directory_iterator(root)) dirs.push_back(e.path());
  std::sort(dirs.begin(), dirs.end());
  ASSERT_GE(dirs.size(), 2u);
  EXPECT_NE(dirs.front().filename(), "000001");
  TimeNs t_prev = 0;
  int pairs = 0;
  std::size_t imu_rows = 0;
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    if (i > 0) {
      EXPECT_EQ(std::stoi(dirs[i].filename().string()),
                std::stoi(dirs[i - 1].filename().string()) + 1);
    }
    const recording::EurocRecording rec = recording::read_euroc(dirs[i]);
    // A pair never straddles two segments.
    ASSERT_EQ(rec.cams[0].frames.size(), rec.cams[1].frames.size()) << dirs[i];
    for (std::size_t k = 0; k < rec.cams[0].frames.size(); ++k) {
      EXPECT_EQ(rec.cams[0].frames[k].t_ns, rec.cams[1].frames[k].t_ns);
    }
    // Segments follow each other with nothing missing: 5 ms IMU rows, 50 ms frames.
    for (const ImuSample& s : rec.imu) {
      if (t_prev != 0) {
        EXPECT_EQ(s.t_ns - t_prev, 5 * kNsPerMs) << dirs[i];
      }
      t_prev = s.t_ns;
    }
    pairs += static_cast<int>(rec.cams[0].frames.size());
    imu_rows += rec.imu.size();
  }
  // The tail of the stream: it ends with the last pair and its rows.
  EXPECT_EQ(t_prev, kNsPerS + (kPairs - 1) * 50 * kNsPerMs + 9 * 5 * kNsPerMs);
  // (A segment may begin between a pair's IMU rows: within one pair's worth of them.)
  EXPECT_NEAR(static_cast<double>(imu_rows), pairs * 10.0, 10.0);
  EXPECT_LT(pairs, kPairs);

  // Never over an earlier run's segments.
  EXPECT_NE(input_error_of([&] {
              recording::RotatingWriter again(root, small_rig(), o);
            }).find("already holds recording segments"),
            std::string::npos);
  fs::remove_all(root);
}

TEST(RotatingWriter, WithoutACapEverySegmentIsKept) {
  const fs::path root = fs::temp_directory_path() / "wallar_rotating_nocap";
  fs::remove_all(root);
  recording::RotationOptions o;
  o.segment_bytes = 3000;
  recording::RotatingWriter w(root, small_rig(), o);
  write_small_stream(w, 12, 3);
  EXPECT_EQ(w.counters().segments_deleted, 0u);
  int pairs = 0;
  for (const fs::path& d : w.segments()) {
    pairs += static_cast<int>(recording::read_euroc(d).cams[0].frames.size());
  }
  EXPECT_EQ(pairs, 12);
  EXPECT_EQ(w.segments().front().filename(), "000001");
  fs::remove_all(root);
}

TEST(RotatingWriter, McapSegmentsAreWholeFilesTheOldestDeletedUnderTheCap) {
  const fs::path root = fs::temp_directory_path() / "wallar_rotating_mcap";
  fs::remove_all(root);
  recording::RotationOptions o;
  o.format = recording::RotationOptions::Format::kMcap;
  o.mcap.chunk_bytes = 1500;  // a chunk (what a segment's size counts) every pair or so
  // A segment starts with its header, schemas and channels: sizes over that.
  std::uint64_t header = 0;
  {
    fs::create_directories(root);
    recording::McapRecordingWriter m(root / "probe.mcap", small_rig(), o.mcap);
    header = m.bytes_written();
  }
  fs::remove_all(root);
  o.segment_bytes = header + 6000;
  o.max_total_bytes = 3 * o.segment_bytes;
  constexpr int kPairs = 60;
  {
    recording::RotatingWriter w(root, small_rig(), o);
    ASSERT_NE(w.current_mcap(), nullptr);
    write_small_stream(w, kPairs, 5, false);
    // More channels may go into the last segment before it closes (the run's outputs).
    const std::uint16_t ch =
        w.current_mcap()->add_json_channel("test.Note", R"({"type":"object"})", "/note");
    w.current_mcap()->write_json(ch, kNsPerS, R"({"n":1})");
    w.close();
    EXPECT_GE(w.counters().segments_started, 4u);
    EXPECT_GE(w.counters().segments_deleted, 1u);
    EXPECT_LE(w.total_bytes(), o.max_total_bytes + o.segment_bytes);
  }
  std::vector<fs::path> files;
  for (const fs::directory_entry& e : fs::directory_iterator(root)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 2u);
  EXPECT_NE(files.front().filename(), "000001.mcap");  // the oldest went under the cap
  TimeNs t_prev = 0;
  for (const fs::path& f : files) {
    EXPECT_EQ(f.extension(), ".mcap");
    const recording::EurocRecording rec = recording::read_recording(f);  // whole, alone
    ASSERT_EQ(rec.cams[0].frames.size(), rec.cams[1].frames.size()) << f;
    for (const ImuSample& s : rec.imu) {
      if (t_prev != 0) {
        EXPECT_EQ(s.t_ns - t_prev, 5 * kNsPerMs) << f;
      }
      t_prev = s.t_ns;
    }
  }
  EXPECT_EQ(t_prev, kNsPerS + (kPairs - 1) * 50 * kNsPerMs + 9 * 5 * kNsPerMs);
  // Never over an earlier run's segments.
  EXPECT_NE(input_error_of([&] {
              recording::RotatingWriter again(root, small_rig(), o);
            }).find("already holds recording segments (0000"),
            std::string::npos);
  fs::remove_all(root);
}

}  // namespace
}  // namespace wallar::test
