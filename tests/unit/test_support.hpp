// SPDX-License-Identifier: Apache-2.0
/// @file test_support.hpp
/// @brief Helpers for tests: temporary folders, a small synthetic EuRoC recording, file edits.
///
/// Threading: test-thread only.
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "wallar/core/error.hpp"
#include "wallar/drivers/recording/euroc.hpp"

namespace wallar::test {

namespace fs = std::filesystem;

/// True under an emulator (qemu-aarch64: the aarch64 test preset sets WALLAR_SHORT_TESTS) or a
/// sanitizer (ASan and TSan run the tracker 5-15x slower), where the slowest tests run the same
/// checks on fewer seeds, frames or rounds, so CI's stages fit its budget.
inline bool short_tests() {
#if defined(WALLAR_SANITIZED)
  return true;
#else
  return std::getenv("WALLAR_SHORT_TESTS") != nullptr;
#endif
}

inline fs::path bundled_recording() { return fs::path(WALLAR_TEST_DATA) / "euroc_v1_01_still"; }

/// A fresh empty folder under the system temp dir, removed at destruction.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() / ("wallar_" + std::string(info->test_suite_name()) + "_" +
                                         info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void spit(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

/// A rig like the headset's: 8x6 gray cameras at 20 Hz, IMU at 200 Hz.
inline RigCalibration small_rig() {
  RigCalibration rig;
  for (int i = 0; i < 2; ++i) {
    CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
    c.name = "cam" + std::to_string(i);
    c.width_px = 8;
    c.height_px = 6;
    c.rate_hz = 20.0;
    c.fx = c.fy = 10.0;
    c.cx = 4.0;
    c.cy = 3.0;
    c.distortion = {0.01, -0.002, 0.0001, 0.0};
    c.T_body_cam.translation() = Eigen::Vector3d(0.055 * (2 * i - 1), 0.0, 0.0);
  }
  rig.imu.rate_hz = 200.0;
  rig.imu.gyro_noise_density = 1.7e-4;
  rig.imu.gyro_random_walk = 1.9e-5;
  rig.imu.accel_noise_density = 2.0e-3;
  rig.imu.accel_random_walk = 3.0e-3;
  return rig;
}

/// Writes `pairs` stereo frames (t = 1 s + k * 50 ms), each after its 10 IMU rows, with seeded
/// random content, and closes the writer.
inline void write_small_stream(recording::RecordingWriter& writer, int pairs, unsigned seed,
                               bool close = true) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> pixel(0, 255);
  std::normal_distribution<double> noise(0.0, 0.01);
  const TimeNs t0 = kNsPerS;
  for (int k = 0; k < pairs; ++k) {
    for (int j = 0; j < 10; ++j) {
      ImuSample s;
      s.t_ns = t0 + k * 50 * kNsPerMs + j * 5 * kNsPerMs;
      s.gyro_rad_s = Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      s.accel_m_s2 = Eigen::Vector3d(noise(rng), noise(rng), 9.81 + noise(rng));
      writer.write_imu(s);
    }
    StereoFrame f;
    f.left.t_ns = f.right.t_ns = f.t_ns = t0 + k * 50 * kNsPerMs;
    f.left.image = Image::allocate(8, 6, PixelFormat::kGray8);
    f.right.image = Image::allocate(8, 6, PixelFormat::kGray8);
    for (int i = 0; i < 48; ++i) {
      f.left.image.mutable_data()[i] = static_cast<std::uint8_t>(pixel(rng));
      f.right.image.mutable_data()[i] = static_cast<std::uint8_t>(pixel(rng));
    }
    writer.write_stereo(f);
  }
  if (close) writer.close();
}
/// The same as a recording; returns its root.
inline fs::path write_small_recording(const fs::path& root, int pairs = 4, unsigned seed = 7) {
  recording::EurocWriter writer(root, small_rig());
  write_small_stream(writer, pairs, seed);
  return root;
}

/// Runs `fn` and returns the InputError message it throws ("" and a test failure if none).
template <typename Fn>
std::string input_error_of(Fn&& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an InputError";
  return "";
}

}  // namespace wallar::test
