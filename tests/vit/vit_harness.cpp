// SPDX-License-Identifier: Apache-2.0
/// @file vit_harness.cpp
/// @brief libwallar_vit.so as Monado uses it: dlopen()ed by path, every VIT symbol resolved by
/// name with dlsym() as Monado's loader does, the interface's major version checked, bad input
/// answered with error results; then a recording's calibration and samples pushed through it
/// (IMU and image pushes in time order, poses popped on another thread) and its trajectory
/// compared with `wallar track --lockstep`'s on the same recording.
///
///   vit_harness --library libwallar_vit.so --recording DIR --reference track.tum
///               [--out vit.tum] [--max-diff-m 0.001] [--check-reset 1]
///
/// Prints one line of figures (JSON) and exits 0 when every check holds, 1 otherwise.
#include <dlfcn.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <opencv2/calib3d.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "wallar/drivers/recording/euroc.hpp"
#include "wallar/drivers/recording/tum_trajectory.hpp"
#include "wallar/dsp/eval/trajectory.hpp"
#include "wallar_vit.h"

namespace {

int g_failures = 0;

// A feature's place through either camera, and over the poses that see it: a fraction of its
// depth (median over features). Measured: 0.006 % and 0.013 % on the EuRoC cut, 0.012 % and
// 0.07 % on the synth-rig clip; leaving out the rectification's rotation, or the cameras'
// distortion, in the library gives 1.35 % and 1.38 % between the EuRoC cut's cameras.
constexpr double kStereoAgreement = 0.002;
constexpr double kWorldAgreement = 0.01;

void check(bool ok, const std::string& what) {
  if (!ok) {
    std::fprintf(stderr, "vit_harness: FAILED: %s\n", what.c_str());
    ++g_failures;
  }
}

// The functions, resolved by name as Monado's t_vit_loader.c does (dlsym, then dlerror()).
struct VitFunctions {
  void* handle = nullptr;
  std::uint32_t major = 0, minor = 0, patch = 0;
  PFN_vit_api_get_version api_get_version = nullptr;
  PFN_vit_tracker_create tracker_create = nullptr;
  PFN_vit_tracker_destroy tracker_destroy = nullptr;
  PFN_vit_tracker_has_image_format tracker_has_image_format = nullptr;
  PFN_vit_tracker_get_supported_extensions tracker_get_supported_extensions = nullptr;
  PFN_vit_tracker_get_enabled_extensions tracker_get_enabled_extensions = nullptr;
  PFN_vit_tracker_enable_extension tracker_enable_extension = nullptr;
  PFN_vit_tracker_start tracker_start = nullptr;
  PFN_vit_tracker_stop tracker_stop = nullptr;
  PFN_vit_tracker_reset tracker_reset = nullptr;
  PFN_vit_tracker_is_running tracker_is_running = nullptr;
  PFN_vit_tracker_push_imu_sample tracker_push_imu_sample = nullptr;
  PFN_vit_tracker_push_img_sample tracker_push_img_sample = nullptr;
  PFN_vit_tracker_add_imu_calibration tracker_add_imu_calibration = nullptr;
  PFN_vit_tracker_add_camera_calibration tracker_add_camera_calibration = nullptr;
  PFN_vit_tracker_pop_pose tracker_pop_pose = nullptr;
  PFN_vit_tracker_get_timing_titles tracker_get_timing_titles = nullptr;
  PFN_vit_pose_destroy pose_destroy = nullptr;
  PFN_vit_pose_get_data pose_get_data = nullptr;
  PFN_vit_pose_get_timing pose_get_timing = nullptr;
  PFN_vit_pose_get_features pose_get_features = nullptr;
};

template <typename Fn>
bool resolve(void* handle, const char* name, Fn& out) {
  dlerror();
  void* sym = dlsym(handle, name);
  if (const char* err = dlerror()) {
    std::fprintf(stderr, "vit_harness: symbol %s: %s\n", name, err);
    return false;
  }
  out = reinterpret_cast<Fn>(sym);
  return out != nullptr;
}

bool load(VitFunctions& v, const char* path) {
  v.handle = dlopen(path, RTLD_LAZY);
  if (v.handle == nullptr) {
    std::fprintf(stderr, "vit_harness: dlopen %s: %s\n", path, dlerror());
    return false;
  }
  // The version first; an unknown major number is refused before anything else is resolved.
  if (!resolve(v.handle, "vit_api_get_version", v.api_get_version)) return false;
  if (v.api_get_version(&v.major, &v.minor, &v.patch) != VIT_SUCCESS ||
      v.major != VIT_HEADER_VERSION_MAJOR) {
    std::fprintf(stderr, "vit_harness: incompatible versions: expecting %d.x.x, got %u.%u.%u\n",
                 VIT_HEADER_VERSION_MAJOR, v.major, v.minor, v.patch);
    return false;
  }
#define WALLAR_VIT_RESOLVE(NAME) ok = resolve(v.handle, "vit_" #NAME, v.NAME) && ok
  bool ok = true;
  WALLAR_VIT_RESOLVE(tracker_create);
  WALLAR_VIT_RESOLVE(tracker_destroy);
  WALLAR_VIT_RESOLVE(tracker_has_image_format);
  WALLAR_VIT_RESOLVE(tracker_get_supported_extensions);
  WALLAR_VIT_RESOLVE(tracker_get_enabled_extensions);
  WALLAR_VIT_RESOLVE(tracker_enable_extension);
  WALLAR_VIT_RESOLVE(tracker_start);
  WALLAR_VIT_RESOLVE(tracker_stop);
  WALLAR_VIT_RESOLVE(tracker_reset);
  WALLAR_VIT_RESOLVE(tracker_is_running);
  WALLAR_VIT_RESOLVE(tracker_push_imu_sample);
  WALLAR_VIT_RESOLVE(tracker_push_img_sample);
  WALLAR_VIT_RESOLVE(tracker_add_imu_calibration);
  WALLAR_VIT_RESOLVE(tracker_add_camera_calibration);
  WALLAR_VIT_RESOLVE(tracker_pop_pose);
  WALLAR_VIT_RESOLVE(tracker_get_timing_titles);
  WALLAR_VIT_RESOLVE(pose_destroy);
  WALLAR_VIT_RESOLVE(pose_get_data);
  WALLAR_VIT_RESOLVE(pose_get_timing);
  WALLAR_VIT_RESOLVE(pose_get_features);
#undef WALLAR_VIT_RESOLVE
  return ok;
}

vit_camera_calibration_t camera_calibration_of(const wallar::RigCalibration& rig, int i) {
  const wallar::CameraCalibration& c = rig.cams[static_cast<std::size_t>(i)];
  vit_camera_calibration_t out{};
  out.camera_index = static_cast<std::uint32_t>(i);
  out.width = c.width_px;
  out.height = c.height_px;
  out.frequency = c.rate_hz;
  out.fx = c.fx;
  out.fy = c.fy;
  out.cx = c.cx;
  out.cy = c.cy;
  out.model = c.distortion.size() == 5 ? VIT_CAMERA_DISTORTION_RT5 : VIT_CAMERA_DISTORTION_RT4;
  out.distortion_count = static_cast<std::uint32_t>(c.distortion.size());
  for (std::size_t k = 0; k < c.distortion.size(); ++k) out.distortion[k] = c.distortion[k];
  const Eigen::Matrix4d T = (rig.imu.T_body_imu.inverse() * c.T_body_cam).matrix();
  for (int r = 0; r < 4; ++r) {
    for (int col = 0; col < 4; ++col) out.transform[r * 4 + col] = T(r, col);
  }
  return out;
}

vit_imu_calibration_t imu_calibration_of(const wallar::ImuCalibration& imu) {
  vit_imu_calibration_t out{};
  out.frequency = imu.rate_hz;
  const double accel_noise[] = {imu.accel_noise_density, imu.accel_random_walk};
  const double gyro_noise[] = {imu.gyro_noise_density, imu.gyro_random_walk};
  for (int k = 0; k < 3; ++k) {
    out.accel.transform[k * 4] = 1.0;
    out.gyro.transform[k * 4] = 1.0;
    out.accel.offset[k] = -imu.accel_bias_m_s2[k];
    out.accel.noise_std[k] = accel_noise[0];
    out.accel.bias_std[k] = accel_noise[1];
    out.gyro.noise_std[k] = gyro_noise[0];
    out.gyro.bias_std[k] = gyro_noise[1];
  }
  return out;
}

// Bad input: error results, never a crash.
void check_bad_input(const VitFunctions& v, const wallar::RigCalibration& rig) {
  vit_tracker_t* t = nullptr;
  check(v.tracker_create(nullptr, &t) == VIT_ERROR_INVALID_VALUE && t == nullptr,
        "create without a config is refused");
  vit_config_t config{nullptr, 3, 1, false};
  check(v.tracker_create(&config, &t) == VIT_ERROR_INVALID_VALUE, "three cameras are refused");
  config = {"/nonexistent/rig.yaml", 2, 1, false};
  check(v.tracker_create(&config, &t) == VIT_ERROR_INVALID_VALUE,
        "a missing calibration file is refused");
  config = {nullptr, 2, 1, false};
  if (v.tracker_create(&config, &t) != VIT_SUCCESS || t == nullptr) {
    check(false, "create with a plain config");
    return;
  }
  check(v.tracker_start(t) == VIT_ERROR_INVALID_VALUE, "start without a calibration is refused");
  vit_imu_sample_t imu{1000, 0, 0, 9.81f, 0, 0, 0};
  check(v.tracker_push_imu_sample(t, &imu) != VIT_SUCCESS, "a push before start is refused");
  vit_camera_calibration_t cam = camera_calibration_of(rig, 0);
  cam.model = VIT_CAMERA_DISTORTION_KB4;
  check(v.tracker_add_camera_calibration(t, &cam) == VIT_ERROR_NOT_SUPPORTED,
        "a Kannala-Brandt camera is not supported");
  cam = camera_calibration_of(rig, 0);
  cam.fx = 0.0;
  check(v.tracker_add_camera_calibration(t, &cam) == VIT_ERROR_INVALID_VALUE,
        "a zero focal length is refused");
  cam = camera_calibration_of(rig, 0);
  cam.camera_index = 2;
  check(v.tracker_add_camera_calibration(t, &cam) == VIT_ERROR_INVALID_VALUE,
        "a third camera index is refused");
  cam = camera_calibration_of(rig, 0);
  cam.transform[0] = 2.0;  // not a rotation
  check(v.tracker_add_camera_calibration(t, &cam) == VIT_ERROR_INVALID_VALUE,
        "a non-rigid T_imu_cam is refused");
  cam = camera_calibration_of(rig, 0);
  cam.transform[3] = NAN;
  check(v.tracker_add_camera_calibration(t, &cam) == VIT_ERROR_INVALID_VALUE,
        "a NaN in T_imu_cam is refused");
  vit_imu_calibration_t imu_cal = imu_calibration_of(rig.imu);
  imu_cal.frequency = -1.0;
  check(v.tracker_add_imu_calibration(t, &imu_cal) == VIT_ERROR_INVALID_VALUE,
        "a negative IMU rate is refused");
  vit_tracker_extension_set_t enabled{};
  check(v.tracker_enable_extension(t, VIT_TRACKER_EXTENSION_POSE_FEATURES, true) == VIT_SUCCESS &&
            v.tracker_get_enabled_extensions(t, &enabled) == VIT_SUCCESS &&
            enabled.has_pose_features,
        "the features extension is enabled");
  check(v.tracker_enable_extension(t, VIT_TRACKER_EXTENSION_POSE_FEATURES, false) == VIT_SUCCESS &&
            v.tracker_get_enabled_extensions(t, &enabled) == VIT_SUCCESS &&
            !enabled.has_pose_features,
        "the features extension is disabled again");
  check(v.tracker_enable_extension(t, static_cast<vit_tracker_extension_t>(5), true) ==
            VIT_ERROR_INVALID_VALUE,
        "an unknown extension is refused");
  vit_pose_t* pose = reinterpret_cast<vit_pose_t*>(&imu);
  check(v.tracker_pop_pose(t, &pose) == VIT_SUCCESS && pose == nullptr,
        "pop_pose on an idle tracker gives no pose");
  v.tracker_destroy(t);
}

// The angle of a pose's rotation [deg].
double angle_deg(const vit_pose_data_t& d) {
  return Eigen::AngleAxisd(Eigen::Quaterniond(d.ow, d.ox, d.oy, d.oz).normalized()).angle() *
         180.0 / M_PI;
}

// Pushes samples [from, to) of the recording in time order (IMU first on ties, left before right).
struct Player {
  const VitFunctions& v;
  vit_tracker_t* t;
  const wallar::recording::EurocRecording& rec;
  const std::array<std::vector<wallar::Image>, 2>& images;
  std::size_t i_imu = 0;
  std::array<std::size_t, 2> i_cam{0, 0};
  std::uint64_t refused = 0;

  static vit_result_t retry(const std::function<vit_result_t()>& push) {
    vit_result_t r;
    while ((r = push()) == VIT_ERROR_ALLOCATION_FAILURE) {
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    return r;
  }

  // Every sample before the time of left image number `frames` (all: SIZE_MAX).
  void play(std::size_t frames) {
    const auto& left = rec.cams[0].frames;
    const std::int64_t until_ns = frames < left.size() ? left[frames].t_ns : INT64_MAX;
    for (;;) {
      std::int64_t t_next = INT64_MAX;
      int which = -1;
      if (i_imu < rec.imu.size()) {
        t_next = rec.imu[i_imu].t_ns;
        which = 2;
      }
      for (int c = 0; c < 2; ++c) {
        const auto& f = rec.cams[static_cast<std::size_t>(c)].frames;
        const std::size_t i = i_cam[static_cast<std::size_t>(c)];
        if (i < f.size() && f[i].t_ns < t_next) {
          t_next = f[i].t_ns;
          which = c;
        }
      }
      if (which < 0 || t_next >= until_ns) break;
      vit_result_t r;
      if (which == 2) {
        const wallar::ImuSample& s = rec.imu[i_imu++];
        const vit_imu_sample_t sample{s.t_ns,
                                      static_cast<float>(s.accel_m_s2.x()),
                                      static_cast<float>(s.accel_m_s2.y()),
                                      static_cast<float>(s.accel_m_s2.z()),
                                      static_cast<float>(s.gyro_rad_s.x()),
                                      static_cast<float>(s.gyro_rad_s.y()),
                                      static_cast<float>(s.gyro_rad_s.z())};
        r = retry([&] { return v.tracker_push_imu_sample(t, &sample); });
      } else {
        const std::size_t k = i_cam[static_cast<std::size_t>(which)]++;
        const wallar::Image& image = images[static_cast<std::size_t>(which)][k];
        vit_img_sample_t sample{};
        sample.cam_index = static_cast<std::uint32_t>(which);
        sample.timestamp = rec.cams[static_cast<std::size_t>(which)].frames[k].t_ns;
        sample.data = const_cast<std::uint8_t*>(image.data());
        sample.width = static_cast<std::uint32_t>(image.width());
        sample.height = static_cast<std::uint32_t>(image.height());
        sample.stride = static_cast<std::uint32_t>(image.stride_bytes());
        sample.size = sample.stride * sample.height;
        sample.format = VIT_IMAGE_FORMAT_L8;
        r = retry([&] { return v.tracker_push_img_sample(t, &sample); });
      }
      if (r != VIT_SUCCESS) ++refused;
    }
  }
};

struct Popped {
  wallar::StampedPose pose;
  bool timing_ok = false;
  std::array<std::vector<vit_pose_feature_t>, 2> features;
  bool features_ok = false;  // both cameras' answered
};

// A feature back in its camera's 3-D frame: undistorted, then along its ray to its depth.
Eigen::Vector3d unproject(const wallar::CameraCalibration& c, const vit_pose_feature_t& f) {
  const cv::Matx33d K(c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
  std::vector<cv::Point2d> in{{f.u, f.v}}, out;
  cv::undistortPoints(in, out, K, c.distortion);
  return Eigen::Vector3d(out[0].x, out[0].y, 1.0) * static_cast<double>(f.depth);
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

struct FeatureFigures {
  double with_20_fraction = 0.0;   // poses with >= 20 left-camera features
  std::size_t outside = 0;         // features off the image or not in front
  double stereo_median_rel = NAN;  // |left - right| in the body frame / depth, per feature
  double world_median_rel = NAN;   // an id's spread in the world over its poses / depth
  std::size_t ids_5 = 0;           // ids seen in >= 5 poses
};

// The pose-features extension checked against geometry the library does not compute for it:
// each feature taken back through its own camera's calibration (undistortion, T_body_cam)
// must land where the other camera's does, and where the same id landed in the other poses.
FeatureFigures feature_figures(const std::vector<Popped>& popped,
                               const wallar::RigCalibration& rig) {
  FeatureFigures out;
  std::size_t with_20 = 0;
  std::vector<double> stereo;
  std::map<std::int64_t, std::vector<Eigen::Vector4d>> by_id;  // world point and depth
  for (const Popped& p : popped) {
    if (p.features[0].size() >= 20) ++with_20;
    std::map<std::int64_t, Eigen::Vector3d> left_body;
    for (std::size_t c = 0; c < 2; ++c) {
      const wallar::CameraCalibration& cam = rig.cams[c];
      for (const vit_pose_feature_t& f : p.features[c]) {
        if (!(f.u >= 0.0f && f.u < static_cast<float>(cam.width_px) && f.v >= 0.0f &&
              f.v < static_cast<float>(cam.height_px) && f.depth > 0.0f)) {
          ++out.outside;
          continue;
        }
        const Eigen::Vector3d p_body = cam.T_body_cam * unproject(cam, f);
        if (c == 0) {
          left_body[f.id] = p_body;
          const Eigen::Vector3d p_world = p.pose.T_world_body * p_body;
          by_id[f.id].push_back(Eigen::Vector4d(p_world.x(), p_world.y(), p_world.z(), f.depth));
        } else if (const auto it = left_body.find(f.id); it != left_body.end()) {
          stereo.push_back((it->second - p_body).norm() / static_cast<double>(f.depth));
        }
      }
    }
  }
  std::vector<double> spread;
  for (const auto& [id, seen] : by_id) {
    if (seen.size() < 5) continue;
    ++out.ids_5;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    double depth = 0.0;
    for (const Eigen::Vector4d& s : seen) {
      mean += s.head<3>();
      depth += s.w();
    }
    mean /= static_cast<double>(seen.size());
    depth /= static_cast<double>(seen.size());
    double worst = 0.0;
    for (const Eigen::Vector4d& s : seen) worst = std::max(worst, (s.head<3>() - mean).norm());
    spread.push_back(worst / depth);
  }
  out.with_20_fraction =
      popped.empty() ? 0.0 : static_cast<double>(with_20) / static_cast<double>(popped.size());
  out.stereo_median_rel = median(stereo);
  out.world_median_rel = median(spread);
  return out;
}

// vit_tracker_reset() while running: tracking starts again, the next poses in a new world
// (the first body pose after the reset), as a restarted tracker's. On a moving recording: the
// pose before the reset is turned, the first after it is not.
void check_reset(const VitFunctions& v, const wallar::recording::EurocRecording& rec,
                 const std::array<std::vector<wallar::Image>, 2>& images) {
  const vit_config_t config{nullptr, 2, rec.imu.empty() ? 0u : 1u, false};
  vit_tracker_t* t = nullptr;
  if (v.tracker_create(&config, &t) != VIT_SUCCESS) return check(false, "create (reset)");
  for (int c = 0; c < 2; ++c) {
    const vit_camera_calibration_t cal = camera_calibration_of(rec.rig(), c);
    v.tracker_add_camera_calibration(t, &cal);
  }
  if (!rec.imu.empty()) {
    const vit_imu_calibration_t cal = imu_calibration_of(rec.rig().imu);
    v.tracker_add_imu_calibration(t, &cal);
  }
  if (v.tracker_start(t) != VIT_SUCCESS) return check(false, "start (reset)");
  // Every pose of the first half out before the reset (poses stop coming for 300 ms).
  auto drain = [&](std::vector<vit_pose_data_t>& into) {
    int quiet_ms = 0;
    while (quiet_ms < 300) {
      vit_pose_t* pose = nullptr;
      if (v.tracker_pop_pose(t, &pose) == VIT_SUCCESS && pose != nullptr) {
        vit_pose_data_t d{};
        v.pose_get_data(pose, &d);
        vit_pose_features_t features{};
        if (v.pose_get_features(pose, 0, &features) != VIT_ERROR_NOT_ENABLED) {
          check(false, "features not enabled: a pose says so");
        }
        v.pose_destroy(pose);
        into.push_back(d);
        quiet_ms = 0;
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        quiet_ms += 10;
      }
    }
  };
  Player player{v, t, rec, images};
  const std::size_t half = rec.cams[0].frames.size() / 2;
  player.play(half);
  std::vector<vit_pose_data_t> before, after;
  drain(before);
  check(v.tracker_reset(t) == VIT_SUCCESS, "reset while running");
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the next supervisor tick
  player.play(SIZE_MAX);
  v.tracker_stop(t);
  drain(after);
  v.tracker_destroy(t);
  check(!before.empty() && !after.empty(), "poses before and after the reset");
  if (before.empty() || after.empty()) return;
  const double turned_before = angle_deg(before.back());
  const double turned_after = angle_deg(after.front());
  std::fprintf(stderr, "vit_harness: reset at frame %zu: %.2f deg turned before, %.3f deg after\n",
               half, turned_before, turned_after);
  check(after.front().timestamp > before.back().timestamp, "poses after the reset are newer");
  check(turned_after < 0.5, "the first pose after the reset starts the new world");
  check(turned_before > 2.0 || rec.ground_truth.empty(), "the headset had turned (a moving clip)");
}

}  // namespace

int main(int argc, char** argv) {
  std::string library, recording, reference, out;
  double max_diff_m = 0.001;
  bool reset = false;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const std::string value = argv[i + 1];
    if (key == "--library") {
      library = value;
    } else if (key == "--recording") {
      recording = value;
    } else if (key == "--reference") {
      reference = value;
    } else if (key == "--out") {
      out = value;
    } else if (key == "--max-diff-m") {
      max_diff_m = std::stod(value);
    } else if (key == "--check-reset") {
      reset = value == "1";
    } else {
      std::fprintf(stderr, "vit_harness: unknown option %s\n", key.c_str());
      return 2;
    }
  }
  if (library.empty() || recording.empty() || reference.empty()) {
    std::fprintf(stderr, "usage: vit_harness --library SO --recording DIR --reference TUM\n");
    return 2;
  }
  VitFunctions v;
  if (!load(v, library.c_str())) return 1;

  const wallar::recording::EurocRecording rec = wallar::recording::read_euroc(recording);
  const wallar::RigCalibration rig = rec.rig();
  check_bad_input(v, rig);

  // The images decoded first, so that pushes go at the tracker's pace, not the decoder's.
  std::array<std::vector<wallar::Image>, 2> images;
  for (int c = 0; c < 2; ++c) {
    for (const auto& f : rec.cams[static_cast<std::size_t>(c)].frames) {
      images[static_cast<std::size_t>(c)].push_back(wallar::recording::load_frame_gray(rec, c, f));
    }
  }

  if (reset) check_reset(v, rec, images);

  vit_config_t config{nullptr, 2, rec.imu.empty() ? 0u : 1u, false};
  vit_tracker_t* t = nullptr;
  if (v.tracker_create(&config, &t) != VIT_SUCCESS) {
    std::fprintf(stderr, "vit_harness: create failed\n");
    return 1;
  }
  vit_tracker_extension_set_t exts{};
  check(v.tracker_get_supported_extensions(t, &exts) == VIT_SUCCESS && exts.has_pose_timing &&
            exts.has_pose_features && exts.has_add_camera_calibration &&
            exts.has_add_imu_calibration,
        "supported extensions: calibrations, timing and features");
  check(v.tracker_enable_extension(t, VIT_TRACKER_EXTENSION_POSE_TIMING, true) == VIT_SUCCESS,
        "timing enabled");
  check(v.tracker_enable_extension(t, VIT_TRACKER_EXTENSION_POSE_FEATURES, true) == VIT_SUCCESS,
        "features enabled");
  bool l8 = false;
  check(v.tracker_has_image_format(t, VIT_IMAGE_FORMAT_L8, &l8) == VIT_SUCCESS && l8, "L8 taken");
  vit_tracker_timing_titles titles{};
  check(v.tracker_get_timing_titles(t, &titles) == VIT_SUCCESS && titles.count >= 3,
        "timing titles");
  for (int c = 0; c < 2; ++c) {
    const vit_camera_calibration_t cal = camera_calibration_of(rig, c);
    check(v.tracker_add_camera_calibration(t, &cal) == VIT_SUCCESS, "camera calibration");
  }
  if (!rec.imu.empty()) {
    const vit_imu_calibration_t cal = imu_calibration_of(rig.imu);
    check(v.tracker_add_imu_calibration(t, &cal) == VIT_SUCCESS, "IMU calibration");
  }
  if (v.tracker_start(t) != VIT_SUCCESS) {
    std::fprintf(stderr, "vit_harness: start failed\n");
    return 1;
  }
  bool running = false;
  check(v.tracker_is_running(t, &running) == VIT_SUCCESS && running, "running after start");
  {
    vit_img_sample_t wrong{};
    std::vector<std::uint8_t> small(16, 0);
    wrong.data = small.data();
    wrong.width = wrong.height = wrong.stride = 4;
    wrong.size = 16;
    wrong.timestamp = 1;
    wrong.format = VIT_IMAGE_FORMAT_L8;
    check(v.tracker_push_img_sample(t, &wrong) == VIT_ERROR_INVALID_VALUE,
          "an image of the wrong size is refused");
  }

  // Poses popped on their own thread while the samples go in, as Monado's consumer does.
  std::atomic<bool> pushing{true};
  std::vector<Popped> popped;
  const std::uint32_t timing_count = titles.count;
  auto pop_all = [&] {
    vit_pose_t* pose = nullptr;
    while (v.tracker_pop_pose(t, &pose) == VIT_SUCCESS && pose != nullptr) {
      vit_pose_data_t d{};
      vit_pose_timing_t timing{};
      Popped p;
      if (v.pose_get_data(pose, &d) == VIT_SUCCESS) {
        p.pose.t_ns = d.timestamp;
        p.pose.T_world_body = wallar::SE3d::Identity();
        p.pose.T_world_body.linear() =
            Eigen::Quaterniond(d.ow, d.ox, d.oy, d.oz).normalized().toRotationMatrix();
        p.pose.T_world_body.translation() = Eigen::Vector3d(d.px, d.py, d.pz);
      }
      if (v.pose_get_timing(pose, &timing) == VIT_SUCCESS && timing.count == timing_count) {
        p.timing_ok = timing.timestamps[0] == d.timestamp && timing.timestamps[1] > 0 &&
                      timing.timestamps[1] <= timing.timestamps[2];
        for (std::uint32_t k = 3; k < timing.count; ++k) {
          p.timing_ok = p.timing_ok && timing.timestamps[k - 1] <= timing.timestamps[k];
        }
      }
      p.features_ok = true;
      for (std::uint32_t c = 0; c < 2; ++c) {
        vit_pose_features_t features{};
        if (v.pose_get_features(pose, c, &features) != VIT_SUCCESS ||
            (features.count > 0 && features.features == nullptr)) {
          p.features_ok = false;
          continue;
        }
        p.features[c].assign(features.features, features.features + features.count);
      }
      vit_pose_features_t third{};
      p.features_ok =
          p.features_ok && v.pose_get_features(pose, 2, &third) == VIT_ERROR_INVALID_VALUE;
      v.pose_destroy(pose);
      popped.push_back(p);
    }
  };
  std::thread consumer([&] {
    while (pushing.load()) {
      pop_all();
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });

  // Time order, IMU first on ties, the left image before the right (as the replay plays it).
  Player player{v, t, rec, images};
  const auto wall_start = std::chrono::steady_clock::now();
  player.play(SIZE_MAX);
  const std::uint64_t refused = player.refused;
  {
    // Out of order and non-finite samples are refused, the run goes on.
    const vit_imu_sample_t old{rec.imu.empty() ? 1 : rec.imu.front().t_ns, 0, 0, 9.81f, 0, 0, 0};
    if (!rec.imu.empty()) {
      check(v.tracker_push_imu_sample(t, &old) == VIT_ERROR_INVALID_VALUE,
            "an IMU sample older than the last is refused");
    }
    const vit_imu_sample_t nan_sample{INT64_MAX, NAN, 0, 9.81f, 0, 0, 0};
    check(v.tracker_push_imu_sample(t, &nan_sample) == VIT_ERROR_INVALID_VALUE,
          "a NaN IMU sample is refused");
  }
  check(v.tracker_stop(t) == VIT_SUCCESS, "stop");
  {
    const vit_imu_sample_t late{INT64_MAX - 1, 0, 0, 9.81f, 0, 0, 0};
    check(v.tracker_push_imu_sample(t, &late) == VIT_ERROR_INVALID_VALUE,
          "a push after stop is refused");
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  pushing.store(false);
  consumer.join();
  pop_all();  // what stop() let finish
  check(v.tracker_is_running(t, &running) == VIT_SUCCESS && !running, "not running after stop");
  check(refused == 0, "every sample taken (" + std::to_string(refused) + " refused)");
  v.tracker_destroy(t);
  dlclose(v.handle);

  // The reference: `wallar track --lockstep` on the same recording, one line per frame.
  std::ifstream in(reference);
  std::stringstream text;
  text << in.rdbuf();
  const std::vector<wallar::StampedPose> ref = wallar::recording::parse_tum(text.str(), reference);
  std::vector<wallar::StampedPose> vit;
  std::size_t timing_ok = 0;
  for (const Popped& p : popped) {
    vit.push_back(p.pose);
    timing_ok += p.timing_ok ? 1 : 0;
  }
  check(timing_ok == popped.size(), "every pose has its timing, in order");
  std::size_t features_ok = 0;
  for (const Popped& p : popped) features_ok += p.features_ok ? 1 : 0;
  check(features_ok == popped.size(), "every pose gives both cameras' features");
  const FeatureFigures ff = feature_figures(popped, rig);
  check(ff.with_20_fraction >= 0.9, "features: 20 or more in the left image of " +
                                        std::to_string(ff.with_20_fraction * 100.0) +
                                        " % of the poses (at least 90 %)");
  check(ff.outside == 0, std::to_string(ff.outside) + " features off their image");
  check(ff.stereo_median_rel <= kStereoAgreement,
        "features: the left and right camera's place of a point differ by " +
            std::to_string(ff.stereo_median_rel * 100.0) + " % of its depth (median)");
  check(ff.world_median_rel <= kWorldAgreement,
        "features: a point's place over the poses that see it spreads by " +
            std::to_string(ff.world_median_rel * 100.0) + " % of its depth (median)");
  check(ff.ids_5 >= 20, "features: " + std::to_string(ff.ids_5) +
                            " points followed over 5 poses or more (at least 20)");
  if (!out.empty()) std::ofstream(out) << wallar::recording::format_tum(vit);

  // Same world (the first body pose's): position differences at the same frame times.
  std::size_t j = 0, matched = 0;
  double sum_sq = 0.0, max_diff = 0.0;
  std::vector<wallar::StampedPose> ref_matched;
  for (const wallar::StampedPose& p : vit) {
    while (j < ref.size() && ref[j].t_ns < p.t_ns) ++j;
    if (j == ref.size() || ref[j].t_ns != p.t_ns) continue;
    const double d = (p.T_world_body.translation() - ref[j].T_world_body.translation()).norm();
    sum_sq += d * d;
    max_diff = std::max(max_diff, d);
    ref_matched.push_back(ref[j]);
    ++matched;
  }
  const double rms_diff = matched > 0 ? std::sqrt(sum_sq / static_cast<double>(matched)) : NAN;
  check(matched == vit.size(), "every VIT pose is at a frame of the reference");
  check(matched >= ref.size() * 9 / 10, "poses for most frames (" + std::to_string(matched) +
                                            " of " + std::to_string(ref.size()) + ")");
  check(rms_diff <= max_diff_m, "position difference to wallar track (RMS " +
                                    std::to_string(rms_diff) + " m) within " +
                                    std::to_string(max_diff_m) + " m");
  // ATE of one against the other (SE(3)-aligned), and of each against the ground truth.
  double ate_between = NAN, ate_vit = NAN, ate_track = NAN;
  if (matched >= 3) {
    wallar::dsp::TrajectoryEvalOptions eo;
    eo.max_dt_ns = 1;
    ate_between = wallar::dsp::evaluate_trajectory(vit, ref_matched, eo).ate_rmse_m;
    check(ate_between <= max_diff_m, "ATE between the trajectories within bound");
  }
  if (!rec.ground_truth.empty() && matched >= 3) {
    std::vector<wallar::StampedPose> gt;
    for (const auto& g : rec.ground_truth) gt.push_back({g.t_ns, g.T_world_body});
    ate_vit = wallar::dsp::evaluate_trajectory(vit, gt).ate_rmse_m;
    ate_track = wallar::dsp::evaluate_trajectory(ref_matched, gt).ate_rmse_m;
  }
  std::printf(
      "{\"recording\": \"%s\", \"version\": \"%u.%u.%u\", \"frames_reference\": %zu, "
      "\"poses_vit\": %zu, \"matched\": %zu, \"position_diff_rms_m\": %.3g, "
      "\"position_diff_max_m\": %.3g, \"ate_between_m\": %.3g, \"ate_vit_vs_gt_m\": %.6f, "
      "\"ate_track_vs_gt_m\": %.6f, \"features_20_fraction\": %.3f, "
      "\"features_stereo_median_rel\": %.5f, \"features_world_median_rel\": %.5f, "
      "\"features_ids_5\": %zu, \"wall_s\": %.2f, \"failures\": %d}\n",
      recording.c_str(), v.major, v.minor, v.patch, ref.size(), vit.size(), matched, rms_diff,
      max_diff, ate_between, ate_vit, ate_track, ff.with_20_fraction, ff.stereo_median_rel,
      ff.world_median_rel, ff.ids_5, wall_s, g_failures);
  return g_failures == 0 ? 0 : 1;
}
