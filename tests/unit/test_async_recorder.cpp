// SPDX-License-Identifier: Apache-2.0
/// @file test_async_recorder.cpp
/// @brief The recorder's writer thread: two producer threads into one recording, read back
/// sample for sample and pixel for pixel; full rings drop and count; a failing disk reports.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <random>
#include <thread>
#include <vector>

#include "test_support.hpp"
#include "wallar/drivers/source/async_recorder.hpp"

namespace wallar::source {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

constexpr int kW = 64;
constexpr int kH = 48;
constexpr TimeNs kT0 = kNsPerS;

RigCalibration rig_64x48() {
  RigCalibration rig = test::small_rig();
  for (CameraCalibration& c : rig.cams) {
    c.width_px = kW;
    c.height_px = kH;
  }
  return rig;
}

AsyncRecorderOptions options_64x48() {
  AsyncRecorderOptions o;
  o.width_px = {kW, kW};
  o.height_px = {kH, kH};
  return o;
}

ImuSample imu_sample(int i, double value) {
  ImuSample s;
  s.t_ns = kT0 + i * 5 * kNsPerMs;  // 200 Hz
  s.gyro_rad_s = Eigen::Vector3d(value, -value, 0.5 * value);
  s.accel_m_s2 = Eigen::Vector3d(0.1 * i, value, 9.81);
  return s;
}

// The pixel of pair k, camera cam at (x, y): distinct per frame and per eye.
std::uint8_t pattern(int k, int cam, int x, int y, std::uint32_t noise) {
  return static_cast<std::uint8_t>(x * 7 + y * 13 + k * 31 + cam * 101 + (noise >> (x % 24)));
}

// A gray image of pair k; the right eye has a padded stride, as some drivers deliver.
Image make_image(int k, int cam, std::uint32_t noise) {
  const int stride = cam == 0 ? kW : kW + 16;
  Image im(HeapImageBuffer::create(static_cast<std::size_t>(stride) * kH), kW, kH, stride,
           PixelFormat::kGray8);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) im.mutable_data()[y * stride + x] = pattern(k, cam, x, y, noise);
  return im;
}

// Overwrites the pixels: what a driver does when it reuses a buffer it got back.
void scribble(Image& im) {
  for (int i = 0; i < im.stride_bytes() * im.height(); ++i) im.mutable_data()[i] = 0xAB;
}

TEST(AsyncRecorder, TwoThreadsEverySampleAndPixelReadBack) {
  TempDir tmp;
  constexpr int kImu = 400;   // 2 s at 200 Hz
  constexpr int kPairs = 40;  // 2 s at 20 Hz
  std::mt19937 rng(42);
  std::vector<double> values(kImu);
  for (double& v : values) v = std::uniform_real_distribution<double>(-1.0, 1.0)(rng);
  std::vector<std::uint32_t> noise(kPairs);
  for (std::uint32_t& n : noise) n = static_cast<std::uint32_t>(rng());

  RecorderCounters c;
  {
    recording::EurocWriter writer(tmp.path(), rig_64x48());
    AsyncRecorder recorder(writer, options_64x48());
    // Four times real time, each thread on its own schedule.
    const auto start = std::chrono::steady_clock::now();
    std::thread imu_thread([&] {
      for (int i = 0; i < kImu; ++i) {
        std::this_thread::sleep_until(start + std::chrono::microseconds(1250) * i);
        recorder.on_imu_sample(imu_sample(i, values[static_cast<std::size_t>(i)]));
      }
    });
    std::thread capture_thread([&] {
      for (int k = 0; k < kPairs; ++k) {
        std::this_thread::sleep_until(start + std::chrono::microseconds(12500) * k);
        StereoFrame f;
        f.sequence = static_cast<std::uint64_t>(k);
        f.t_ns = f.left.t_ns = kT0 + k * 50 * kNsPerMs;  // ties with an IMU sample
        f.right.t_ns = f.left.t_ns + 1000;
        f.left.image = make_image(k, 0, noise[static_cast<std::size_t>(k)]);
        f.right.image = make_image(k, 1, noise[static_cast<std::size_t>(k)]);
        recorder.on_stereo(f);
        scribble(f.left.image);  // the recorder copied: reusing the buffers changes nothing
        scribble(f.right.image);
      }
    });
    imu_thread.join();
    capture_thread.join();
    c = recorder.close();
    EXPECT_EQ(recorder.close().imu_written, c.imu_written);  // idempotent
  }

  EXPECT_EQ(c.error, "");
  EXPECT_EQ(c.imu_written, static_cast<std::uint64_t>(kImu));
  EXPECT_EQ(c.frames_written[0], static_cast<std::uint64_t>(kPairs));
  EXPECT_EQ(c.frames_written[1], static_cast<std::uint64_t>(kPairs));
  EXPECT_EQ(c.pairs_written, static_cast<std::uint64_t>(kPairs));
  EXPECT_EQ(c.imu_dropped, 0u);
  EXPECT_EQ(c.frames_dropped, 0u);
  EXPECT_EQ(c.write_errors, 0u);
  EXPECT_EQ(c.frames_not_copied, 0u);
  EXPECT_EQ(c.lost(), 0u);
  EXPECT_GE(c.imu_high_water, 1u);
  EXPECT_LE(c.imu_high_water, 16384u);
  EXPECT_GE(c.frame_high_water, 1u);
  EXPECT_LE(c.frame_high_water, 16u);

  const recording::EurocRecording rec = recording::read_euroc(tmp.path());
  ASSERT_EQ(rec.imu.size(), static_cast<std::size_t>(kImu));
  for (int i = 0; i < kImu; ++i) {
    const ImuSample want = imu_sample(i, values[static_cast<std::size_t>(i)]);
    const ImuSample& got = rec.imu[static_cast<std::size_t>(i)];
    ASSERT_EQ(got.t_ns, want.t_ns) << i;
    EXPECT_EQ(got.gyro_rad_s, want.gyro_rad_s) << i;
    EXPECT_EQ(got.accel_m_s2, want.accel_m_s2) << i;
  }
  for (int cam = 0; cam < 2; ++cam) {
    const recording::CameraStream& stream = rec.cams[static_cast<std::size_t>(cam)];
    ASSERT_EQ(stream.frames.size(), static_cast<std::size_t>(kPairs));
    for (int k = 0; k < kPairs; ++k) {
      const recording::FrameEntry& e = stream.frames[static_cast<std::size_t>(k)];
      ASSERT_EQ(e.t_ns, kT0 + k * 50 * kNsPerMs + (cam == 1 ? 1000 : 0));
      const Image im = recording::load_png_gray(stream.image_path(e), kW, kH);
      int wrong = 0;
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
          wrong += im.row(y)[x] != pattern(k, cam, x, y, noise[static_cast<std::size_t>(k)]);
      EXPECT_EQ(wrong, 0) << "cam" << cam << " pair " << k;
    }
    // No temporary files left behind.
    for (const auto& f : fs::directory_iterator(stream.dir / "data"))
      EXPECT_EQ(f.path().extension(), ".png") << f.path();
  }
}

TEST(AsyncRecorder, TinyRingsDropAndCountButKeepOrder) {
  TempDir tmp;
  constexpr int kImu = 10000;
  constexpr int kPairs = 50;
  RecorderCounters c;
  {
    recording::EurocWriter writer(tmp.path(), rig_64x48());
    AsyncRecorderOptions o = options_64x48();
    o.imu_capacity = 4;
    o.frame_capacity = 1;
    AsyncRecorder recorder(writer, o);
    for (int i = 0; i < kImu; ++i) recorder.on_imu(imu_sample(i, i * 1e-4));
    for (int k = 0; k < kPairs; ++k) {
      StereoFrame f;
      f.t_ns = f.left.t_ns = f.right.t_ns = kT0 + k * 50 * kNsPerMs;
      f.left.image = make_image(k, 0, 1u);
      f.right.image = make_image(k, 1, 1u);
      recorder.on_stereo(f);
    }
    c = recorder.close();
  }
  EXPECT_EQ(c.error, "");
  EXPECT_EQ(c.write_errors, 0u);
  EXPECT_EQ(c.imu_written + c.imu_dropped, static_cast<std::uint64_t>(kImu));
  EXPECT_GT(c.imu_dropped, 0u);
  EXPECT_LE(c.imu_high_water, 4u);
  EXPECT_EQ(c.frames_written[0], c.pairs_written);
  EXPECT_EQ(c.frames_written[1], c.pairs_written);
  EXPECT_EQ(2 * c.pairs_written + c.frames_dropped, static_cast<std::uint64_t>(2 * kPairs));
  EXPECT_LE(c.frame_high_water, 1u);
  EXPECT_EQ(c.lost(), c.imu_dropped + c.frames_dropped);

  const recording::EurocRecording rec = recording::read_euroc(tmp.path());
  ASSERT_EQ(rec.imu.size(), c.imu_written);
  for (std::size_t i = 1; i < rec.imu.size(); ++i) {
    ASSERT_GT(rec.imu[i].t_ns, rec.imu[i - 1].t_ns) << i;
    // Each row is the sample pushed at its time, whole.
    const auto idx = static_cast<int>((rec.imu[i].t_ns - kT0) / (5 * kNsPerMs));
    EXPECT_EQ(rec.imu[i].gyro_rad_s, imu_sample(idx, idx * 1e-4).gyro_rad_s) << i;
  }
  EXPECT_EQ(rec.cams[0].frames.size(), c.pairs_written);
}

TEST(AsyncRecorder, WaitWhenFullLosesNothing) {
  TempDir tmp;
  constexpr int kImu = 300;
  RecorderCounters c;
  {
    recording::EurocWriter writer(tmp.path(), rig_64x48());
    AsyncRecorderOptions o = options_64x48();
    o.imu_capacity = 4;
    o.frame_capacity = 1;
    o.wait_when_full = true;
    AsyncRecorder recorder(writer, o);
    for (int i = 0; i < kImu; ++i) {
      recorder.on_imu(imu_sample(i, 0.0));
      if (i % 10 == 0) {
        CameraFrame f;
        f.t_ns = imu_sample(i, 0.0).t_ns;
        f.image = make_image(i, 1, 3u);
        recorder.on_unpaired(1, f);
      }
    }
    c = recorder.close();
  }
  EXPECT_EQ(c.lost(), 0u);
  EXPECT_EQ(c.imu_written, static_cast<std::uint64_t>(kImu));
  EXPECT_EQ(c.frames_written[0], 0u);
  EXPECT_EQ(c.frames_written[1], static_cast<std::uint64_t>(kImu / 10));
  EXPECT_EQ(c.pairs_written, 0u);
  const recording::EurocRecording rec = recording::read_euroc(tmp.path());
  EXPECT_EQ(rec.imu.size(), static_cast<std::size_t>(kImu));
  EXPECT_EQ(rec.cams[1].frames.size(), static_cast<std::size_t>(kImu / 10));
}

// Counts what the recorder hands it, and whether it was closed.
class CountingWriter final : public recording::RecordingWriter {
 public:
  void write_imu(const ImuSample& /*sample*/) override { ++imu; }
  void write_camera(int /*cam*/, const CameraFrame& /*frame*/) override { ++frames; }
  void close() override { ++closes; }
  int imu = 0, frames = 0, closes = 0;
};

TEST(AsyncRecorder, LeavesTheWriterOpenWhenAskedSoTheOwnerCanAddToIt) {
  CountingWriter writer;
  AsyncRecorderOptions o = options_64x48();
  o.close_writer = false;  // `wallar run --record`: the run's outputs follow
  {
    AsyncRecorder recorder(writer, o);
    for (int i = 0; i < 20; ++i) recorder.on_imu(imu_sample(i, 0.0));
    const RecorderCounters c = recorder.close();
    EXPECT_EQ(c.imu_written, 20u);
    EXPECT_EQ(writer.imu, 20);  // drained before close() returned
    EXPECT_EQ(writer.closes, 0);
  }
  EXPECT_EQ(writer.closes, 0);  // nor by the destructor
  CountingWriter closed;
  { AsyncRecorder recorder(closed, options_64x48()); }
  EXPECT_EQ(closed.closes, 1);  // the default: the recorder closes it
}

TEST(AsyncRecorder, ReferencesAreGivenBackOnceWritten) {
  TempDir tmp;
  // copy_frames off, and copies on with slot buffers too small: both keep the source's image.
  for (const bool copy : {false, true}) {
    const fs::path root = tmp.path() / (copy ? "small_slots" : "references");
    const Image left = make_image(0, 0, 5u);
    const Image right = make_image(0, 1, 5u);
    RecorderCounters c;
    {
      recording::EurocWriter writer(root, rig_64x48());
      AsyncRecorderOptions o;
      o.copy_frames = copy;
      o.width_px = {8, 8};
      o.height_px = {6, 6};
      AsyncRecorder recorder(writer, o);
      StereoFrame f;
      f.t_ns = f.left.t_ns = f.right.t_ns = kT0;
      f.left.image = left;
      f.right.image = right;
      recorder.on_stereo(f);
      c = recorder.close();
      EXPECT_EQ(left.use_count(), 2) << "f still holds one";
    }
    EXPECT_EQ(left.use_count(), 1) << "the recorder let go of its reference";
    EXPECT_EQ(right.use_count(), 1);
    EXPECT_EQ(c.pairs_written, 1u);
    EXPECT_EQ(c.frames_not_copied, copy ? 2u : 0u);
    const recording::EurocRecording rec = recording::read_euroc(root);
    const Image im = recording::load_png_gray(rec.cams[1].image_path(rec.cams[1].frames.at(0)));
    EXPECT_EQ(im.row(7)[9], pattern(0, 1, 9, 7, 5u));
  }
}

TEST(AsyncRecorder, UnwritableDestinationReportsAndDoesNotHang) {
  TempDir tmp;
  constexpr int kImu = 200;
  constexpr int kFrames = 10;
  RecorderCounters c;
  {
    recording::EurocWriter writer(tmp.path(), rig_64x48());
    // cam0/data becomes a regular file: no image can be created under it (even as root).
    const fs::path data = tmp.path() / "mav0" / "cam0" / "data";
    fs::remove_all(data);
    test::spit(data, "not a folder\n");
    AsyncRecorder recorder(writer, options_64x48());
    for (int i = 0; i < kImu; ++i) {
      recorder.on_imu(imu_sample(i, 0.25));
      if (i % 20 == 10) {
        CameraFrame f;
        f.t_ns = imu_sample(i, 0.0).t_ns;
        f.image = make_image(i, 0, 9u);
        recorder.on_unpaired(0, f);
      }
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    c = recorder.close();
  }
  EXPECT_NE(c.error, "");
  EXPECT_EQ(c.error.find('\n'), std::string::npos);
  EXPECT_NE(c.error.find("cam0"), std::string::npos) << c.error;
  EXPECT_EQ(c.frames_written[0], 0u);
  EXPECT_GE(c.write_errors, 1u);
  EXPECT_EQ(c.imu_dropped + c.frames_dropped, 0u);
  // Every sample is accounted for: written before the failure, or lost to it.
  EXPECT_EQ(c.imu_written + c.frames_written[0] + c.write_errors,
            static_cast<std::uint64_t>(kImu + kFrames));
  EXPECT_EQ(c.lost(), c.write_errors);
  // What was written before the failure is a readable recording.
  const recording::EurocRecording rec = recording::read_euroc_imu(tmp.path());
  EXPECT_EQ(rec.imu.size(), c.imu_written);
}

}  // namespace
}  // namespace wallar::source
