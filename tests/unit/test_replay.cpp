// SPDX-License-Identifier: Apache-2.0
/// @file test_replay.cpp
/// @brief Stereo pairing, replay pacing and order, and the record -> replay round trip.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>

#include "test_support.hpp"
#include "wallar/drivers/source/recorder_sink.hpp"
#include "wallar/drivers/source/replay_source.hpp"
#include "wallar/drivers/sync/stereo_pairer.hpp"

namespace wallar::test {
namespace {

CameraFrame frame_at(TimeNs t_ns) {
  CameraFrame f;
  f.t_ns = t_ns;
  return f;
}

TEST(StereoPairer, PairsWithinToleranceInEitherArrivalOrder) {
  sync::StereoPairer p(5 * kNsPerMs);
  EXPECT_FALSE(p.push(0, frame_at(100 * kNsPerMs)).pair);
  auto r = p.push(1, frame_at(103 * kNsPerMs));
  ASSERT_TRUE(r.pair);
  EXPECT_EQ(r.pair->left.t_ns, 100 * kNsPerMs);
  EXPECT_EQ(r.pair->right.t_ns, 103 * kNsPerMs);
  EXPECT_EQ(r.pair->skew_ns(), 3 * kNsPerMs);
  EXPECT_FALSE(p.push(1, frame_at(150 * kNsPerMs)).pair);  // right first this time
  r = p.push(0, frame_at(148 * kNsPerMs));
  ASSERT_TRUE(r.pair);
  EXPECT_EQ(r.pair->sequence, 1u);
  EXPECT_EQ(p.stats().pairs, 2u);
  EXPECT_EQ(p.stats().max_abs_skew_ns, 3 * kNsPerMs);
}

TEST(StereoPairer, SyncAssessmentWarnsUnderNinetyPercentPairedOrAboveHalfTheTolerance) {
  sync::PairingStats s;
  s.pairs = 90;
  s.unpaired = {10, 10};  // 180 of 200 frames paired
  s.sum_abs_skew_ns = 90 * 2e6;
  s.max_abs_skew_ns = 4 * kNsPerMs;
  sync::SyncAssessment a = sync::assess_sync(s, 8 * kNsPerMs);
  EXPECT_EQ(a.frames, 200u);
  EXPECT_DOUBLE_EQ(a.paired_percent, 90.0);
  EXPECT_DOUBLE_EQ(a.mean_skew_ms, 2.0);
  EXPECT_DOUBLE_EQ(a.max_skew_ms, 4.0);
  EXPECT_FALSE(a.warn());  // 90 % and exactly half the tolerance: both still fine
  s.unpaired = {11, 10};
  EXPECT_TRUE(sync::assess_sync(s, 8 * kNsPerMs).low_pairing);
  s.unpaired = {0, 0};
  s.max_abs_skew_ns = 4 * kNsPerMs + 1;
  a = sync::assess_sync(s, 8 * kNsPerMs);
  EXPECT_TRUE(a.high_skew);
  EXPECT_FALSE(a.low_pairing);
  EXPECT_TRUE(sync::assess_sync(sync::PairingStats{}, 8 * kNsPerMs).low_pairing);  // no frames
}

TEST(StereoPairer, CountsAndReturnsFramesThatFindNoPartner) {
  sync::StereoPairer p(5 * kNsPerMs);
  (void)p.push(0, frame_at(100 * kNsPerMs));
  // The right camera skipped 100 ms: the left frame can never be paired now.
  auto r = p.push(1, frame_at(150 * kNsPerMs));
  EXPECT_FALSE(r.pair);
  ASSERT_TRUE(r.unpaired[0]);
  EXPECT_EQ(r.unpaired[0]->t_ns, 100 * kNsPerMs);
  // A second left frame replaces nothing: the pending right pairs with it.
  r = p.push(0, frame_at(151 * kNsPerMs));
  ASSERT_TRUE(r.pair);
  // Two lefts in a row: the first is given up.
  (void)p.push(0, frame_at(200 * kNsPerMs));
  r = p.push(0, frame_at(250 * kNsPerMs));
  ASSERT_TRUE(r.unpaired[0]);
  EXPECT_EQ(r.unpaired[0]->t_ns, 200 * kNsPerMs);
  const auto rest = p.flush();
  ASSERT_TRUE(rest[0]);
  EXPECT_EQ(rest[0]->t_ns, 250 * kNsPerMs);
  EXPECT_EQ(p.stats().unpaired[0], 3u);
  EXPECT_EQ(p.stats().unpaired[1], 0u);
  EXPECT_EQ(p.stats().pairs, 1u);
}

// Records what a consumer sees, in order.
class Probe final : public source::SensorSink {
 public:
  void on_imu(const ImuSample& s) override {
    EXPECT_GT(s.t_ns, last_imu_t_ns);
    EXPECT_GT(s.publish_t_ns, 0);
    last_imu_t_ns = s.t_ns;
    imu.push_back(s);
    order.push_back('i');
  }
  void on_stereo(const StereoFrame& f) override {
    EXPECT_GE(f.t_ns, last_imu_t_ns);  // the IMU up to a frame arrives before the frame
    frames.push_back(f);
    order.push_back('s');
  }
  void on_unpaired(int cam, const CameraFrame& f) override { unpaired.emplace_back(cam, f.t_ns); }
  TimeNs last_imu_t_ns = 0;
  std::vector<ImuSample> imu;
  std::vector<StereoFrame> frames;
  std::vector<std::pair<int, TimeNs>> unpaired;
  std::string order;
};

TEST(ReplaySource, PlaysEverythingInTimeOrderAsFastAsPossible) {
  TempDir tmp;
  write_small_recording(tmp.path(), 6);
  const auto rec = recording::read_euroc(tmp.path());
  Probe probe;
  std::atomic<bool> stop{false};
  source::ReplayOptions opt;
  opt.rate = 0.0;
  const auto stats = source::ReplaySource(rec, opt).run(probe, stop);
  EXPECT_EQ(stats.imu_samples, 60u);
  EXPECT_EQ(stats.pairs_delivered, 6u);
  EXPECT_EQ(stats.pairing.unpaired[0] + stats.pairing.unpaired[1], 0u);
  ASSERT_EQ(probe.frames.size(), 6u);
  EXPECT_EQ(probe.frames[3].left.image.width(), 8);
  // The IMU sample stamped with a frame comes first, then the pair, then the rest of the IMU.
  EXPECT_EQ(probe.order.substr(0, 12), "is" + std::string(10, 'i'));
}

TEST(ReplaySource, RealTimePacingTakesTheRecordingsDuration) {
  TempDir tmp;
  write_small_recording(tmp.path(), 5);  // 1.000 .. 1.245 s of IMU, frames to 1.200 s
  const auto rec = recording::read_euroc(tmp.path());
  Probe probe;
  std::atomic<bool> stop{false};
  source::ReplayOptions opt;
  opt.rate = 2.0;  // twice real time: 245 ms of data in about 122 ms
  const auto stats = source::ReplaySource(rec, opt).run(probe, stop);
  EXPECT_GE(stats.wall_time_ns, 120 * kNsPerMs);
  EXPECT_EQ(stats.imu_samples, 50u);
}

TEST(ReplaySource, StartOffsetAndSkip) {
  TempDir tmp;
  write_small_recording(tmp.path(), 8);
  const auto rec = recording::read_euroc(tmp.path());
  Probe probe;
  std::atomic<bool> stop{false};
  source::ReplayOptions opt;
  opt.rate = 0.0;
  opt.start_offset_ns = 100 * kNsPerMs;  // drops frames 0 and 1 and their IMU
  opt.skip = 1;                          // then every other pair
  const auto stats = source::ReplaySource(rec, opt).run(probe, stop);
  EXPECT_EQ(stats.imu_samples, 60u);
  ASSERT_EQ(probe.frames.size(), 3u);
  EXPECT_EQ(probe.frames[0].t_ns, kNsPerS + 100 * kNsPerMs);
  EXPECT_EQ(probe.frames[1].t_ns, kNsPerS + 200 * kNsPerMs);
  EXPECT_EQ(stats.pairs_skipped, 3u);
}

TEST(ReplaySource, HandsUnpairedFramesToTheSink) {
  TempDir tmp;
  write_small_recording(tmp.path(), 4);
  // Remove the second right frame from the CSV.
  const fs::path csv = tmp.path() / "mav0" / "cam1" / "data.csv";
  std::string text = slurp(csv);
  text.erase(text.find("1050000000,1050000000.png\n"), 26);
  spit(csv, text);
  const auto rec = recording::read_euroc(tmp.path());
  Probe probe;
  std::atomic<bool> stop{false};
  const auto stats = source::ReplaySource(rec, {.rate = 0.0}).run(probe, stop);
  EXPECT_EQ(stats.pairs_delivered, 3u);
  EXPECT_EQ(stats.pairing.unpaired[0], 1u);
  ASSERT_EQ(probe.unpaired.size(), 1u);
  EXPECT_EQ(probe.unpaired[0], std::make_pair(0, TimeNs{1050000000}));
}

TEST(ReplaySource, StopsWhenAsked) {
  TempDir tmp;
  write_small_recording(tmp.path(), 4);
  const auto rec = recording::read_euroc(tmp.path());
  Probe probe;
  std::atomic<bool> stop{true};
  const auto stats = source::ReplaySource(rec, {.rate = 1.0}).run(probe, stop);
  EXPECT_TRUE(stats.stopped);
  EXPECT_EQ(stats.imu_samples, 0u);
}

// The recorder is a sink: replaying the bundled real recording into the writer must give
// byte-identical CSVs and pixel-identical images.

TEST(RecordReplay, RoundTripsTheBundledRecordingExactly) {
  TempDir tmp;
  const auto original = recording::read_euroc(bundled_recording());
  {
    recording::EurocWriter writer(tmp.path(), original.rig());
    source::RecorderSink rec(writer);
    std::atomic<bool> stop{false};
    (void)source::ReplaySource(original, {.rate = 0.0}).run(rec, stop);
    writer.close();
  }
  for (const char* csv : {"cam0/data.csv", "cam1/data.csv", "imu0/data.csv"}) {
    EXPECT_EQ(slurp(tmp.path() / "mav0" / csv), slurp(bundled_recording() / "mav0" / csv)) << csv;
  }
  const auto copy = recording::read_euroc(tmp.path());
  EXPECT_EQ(copy.rig().cams[0].fx, original.rig().cams[0].fx);
  EXPECT_TRUE(copy.cams[1].calib.T_body_cam.isApprox(original.cams[1].calib.T_body_cam, 1e-15));
  for (int c = 0; c < 2; ++c) {
    const auto& a = original.cams[static_cast<std::size_t>(c)];
    const auto& b = copy.cams[static_cast<std::size_t>(c)];
    ASSERT_EQ(a.frames.size(), b.frames.size());
    for (std::size_t i = 0; i < a.frames.size(); i += 13) {
      const Image ia = recording::load_png_gray(a.image_path(a.frames[i]));
      const Image ib = recording::load_png_gray(b.image_path(b.frames[i]));
      ASSERT_EQ(ia.width() * ia.height(), ib.width() * ib.height());
      EXPECT_EQ(
          0, std::memcmp(ia.data(), ib.data(), static_cast<std::size_t>(ia.width()) * ia.height()))
          << "frame " << i << " of cam" << c;
    }
  }
}

}  // namespace
}  // namespace wallar::test
