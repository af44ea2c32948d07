// SPDX-License-Identifier: Apache-2.0
/// @file wallar_vit.cpp
/// @brief The VIT interface over the appliance: calibrations -> the rig, pushes -> the push
/// module, the tracking thread's frames -> poses (wallar_vit.h has the contract).
#define WALLAR_VIT_PROTOTYPES
#include "wallar_vit.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <new>
#include <opencv2/calib3d.hpp>
#include <string>
#include <thread>
#include <vector>

#include "wallar/drivers/recording/calibration_files.hpp"
#include "wallar/firmware/appliance.hpp"
#include "wallar/firmware/appliance/push_module.hpp"
#include "wallar/firmware/offline.hpp"

#define WALLAR_VIT_EXPORT extern "C" __attribute__((visibility("default")))

namespace {

using wallar::DurationNs;
using wallar::TimeNs;

// The pose-timing extension's time stamps (CLOCK_MONOTONIC but the first, the frame's time).
constexpr std::array<const char*, 8> kTimingTitles = {
    "frame_ts",     "pushed",      "tracking_start", "rectified",
    "pyramid_done", "stage1_done", "stage2_done",    "pose_produced"};
constexpr std::size_t kMaxQueuedPoses = 1024;  // a consumer that stopped popping loses the oldest

void vit_log(const char* format, ...) __attribute__((format(printf, 1, 2)));
void vit_log(const char* format, ...) {
  char line[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  std::fprintf(stderr, "wallar_vit: %s\n", line);
}

bool all_finite(const double* v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(v[i])) return false;
  }
  return true;
}

// One figure for three axes: their mean (the figure itself when they agree, exactly).
double one_of_three(const double* v) {
  return v[0] == v[1] && v[1] == v[2] ? v[0] : (v[0] + v[1] + v[2]) / 3.0;
}

// An enumerator as the caller passed it: C may pass any int, which a C++ load of the enum type
// would not take (a value outside its range is undefined behaviour), so the bytes are read.
template <typename Enum>
int raw_enum(const Enum& e) {
  static_assert(sizeof(Enum) == sizeof(int));
  int v = 0;
  std::memcpy(&v, &e, sizeof v);
  return v;
}

// A row-major 3x3 as a matrix.
Eigen::Matrix3d matrix3_of(const double* m) {
  Eigen::Matrix3d out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out(r, c) = m[r * 3 + c];
  }
  return out;
}

}  // namespace

struct vit_pose {
  vit_pose_data_t data{};
  bool has_timing = false;
  std::array<std::int64_t, kTimingTitles.size()> timing{};
  bool has_features = false;
  std::array<std::vector<vit_pose_feature_t>, 2> features;  // per camera
};

struct vit_tracker {
  wallar::RigCalibration rig;
  std::string rig_source = "the VIT calibration";
  std::array<bool, 2> camera_given{false, false};
  bool imu_given = false;
  // The IMU calibration's raw-sample corrections beyond the rig's accelerometer bias.
  Eigen::Matrix3d accel_transform = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d gyro_transform = Eigen::Matrix3d::Identity();
  Eigen::Vector3d gyro_offset = Eigen::Vector3d::Zero();
  std::atomic<bool> timing_enabled{false};
  std::atomic<bool> features_enabled{false};

  // While running. Push modules are kept until destroy: a push racing a stop finds its module.
  std::vector<std::unique_ptr<wallar::firmware::PushModule>> modules;
  std::atomic<wallar::firmware::PushModule*> push{nullptr};
  std::array<std::uint64_t, 2> sequence{0, 0};  // the image pusher's
  std::thread worker;
  std::atomic<bool> stop{false}, reset_requested{false}, worker_done{false};
  std::string worker_error;  // written by the worker before worker_done

  // Poses: produced on the tracking thread, popped by the consumer.
  std::mutex poses_mutex;
  std::deque<vit_pose*> poses;
  std::uint64_t poses_dropped = 0;
  bool have_last = false;  // the tracking thread's (velocity)
  TimeNs last_t_ns = 0;
  Eigen::Vector3d last_p = Eigen::Vector3d::Zero();
  std::atomic<bool> forget_last{false};
  std::vector<wallar::dsp::FrameFeature> frame_features;  // the tracking thread's
  std::array<std::vector<cv::Point3d>, 2> feature_points;
  std::array<std::vector<cv::Point2d>, 2> feature_pixels;
  std::array<std::vector<std::int64_t>, 2> feature_ids;

  ~vit_tracker() { clear_poses(); }

  void clear_poses() {
    const std::lock_guard lock(poses_mutex);
    for (vit_pose* p : poses) delete p;
    poses.clear();
  }

  // The tracking thread: one pose per tracked frame.
  void on_frame_pose(const wallar::firmware::FramePose& f) {
    if (forget_last.exchange(false)) have_last = false;
    if (f.rejected || f.state != wallar::dsp::TrackingState::kTracking) return;
    auto* pose = new (std::nothrow) vit_pose;
    if (pose == nullptr) return;
    const Eigen::Vector3d p = f.T_world_body.translation();
    const Eigen::Quaterniond q(f.T_world_body.linear());
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    if (have_last && f.t_ns > last_t_ns) {
      v = (p - last_p) / wallar::ns_to_s(f.t_ns - last_t_ns);
    }
    have_last = true;
    last_t_ns = f.t_ns;
    last_p = p;
    pose->data.timestamp = f.t_ns;
    pose->data.px = static_cast<float>(p.x());
    pose->data.py = static_cast<float>(p.y());
    pose->data.pz = static_cast<float>(p.z());
    pose->data.ox = static_cast<float>(q.x());
    pose->data.oy = static_cast<float>(q.y());
    pose->data.oz = static_cast<float>(q.z());
    pose->data.ow = static_cast<float>(q.w());
    pose->data.vx = static_cast<float>(v.x());
    pose->data.vy = static_cast<float>(v.y());
    pose->data.vz = static_cast<float>(v.z());
    if (features_enabled.load(std::memory_order_relaxed) && f.tracker != nullptr) {
      add_features(*f.tracker, *pose);
    }
    if (timing_enabled.load(std::memory_order_relaxed)) {
      pose->has_timing = true;
      TimeNs t = f.taken_ns;
      pose->timing = {f.t_ns,
                      f.publish_t_ns,
                      t,
                      t += f.times.rectify_ns,
                      t += f.times.pyramid_ns,
                      t += f.times.stage1_ns,
                      t += f.times.stage2_ns,
                      wallar::monotonic_now_ns()};
    }
    const std::lock_guard lock(poses_mutex);
    if (poses.size() >= kMaxQueuedPoses) {
      delete poses.front();
      poses.pop_front();
      ++poses_dropped;
    }
    poses.push_back(pose);
  }

  // The frame's tracked points where each camera saw them, in the pushed images' pixels (the
  // tracker measures in rectified images: each observation goes back through its camera's
  // rectification and distortion), with the point's depth in that camera.
  void add_features(const wallar::dsp::Tracker& tracker, vit_pose& pose) {
    if (frame_features.empty()) {
      frame_features.resize(static_cast<std::size_t>(tracker.config().max_tracks));
    }
    const std::size_t n = tracker.frame_features(frame_features);
    const wallar::dsp::StereoIntrinsics& K = tracker.intrinsics();
    for (std::size_t c = 0; c < 2; ++c) {
      feature_points[c].clear();
      feature_ids[c].clear();
    }
    for (std::size_t i = 0; i < n; ++i) {
      const wallar::dsp::FrameFeature& ff = frame_features[i];
      const double z = ff.depth_m;
      const double y = (ff.v_px - K.cy_px) * z / K.f_px;
      const std::int64_t id = static_cast<std::int64_t>(ff.point.generation) << 32 |
                              static_cast<std::uint32_t>(ff.point.id);
      // In the rectified left camera: the left observation, and the right one (its camera
      // sits baseline_m along +x).
      feature_points[0].emplace_back((ff.u_px - K.cx_px) * z / K.f_px, y, z);
      feature_ids[0].push_back(id);
      if (std::isfinite(ff.u_right_px)) {
        feature_points[1].emplace_back((ff.u_right_px - K.cx_px) * z / K.f_px + K.baseline_m, y, z);
        feature_ids[1].push_back(id);
      }
    }
    for (std::size_t c = 0; c < 2; ++c) {
      const wallar::CameraCalibration& cam = rig.cams[c];
      const wallar::SE3d T_cam_rect = cam.T_body_cam.inverse() * tracker.T_body_rect();
      std::vector<vit_pose_feature_t>& out = pose.features[c];
      out.clear();
      for (cv::Point3d& p : feature_points[c]) {
        const Eigen::Vector3d q = T_cam_rect * Eigen::Vector3d(p.x, p.y, p.z);
        p = {q.x(), q.y(), q.z()};
      }
      if (feature_points[c].empty()) continue;
      const cv::Matx33d Kc(cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0);
      cv::projectPoints(feature_points[c], cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), Kc,
                        cam.distortion, feature_pixels[c]);
      for (std::size_t i = 0; i < feature_points[c].size(); ++i) {
        const cv::Point2d& uv = feature_pixels[c][i];
        const double depth = feature_points[c][i].z;
        // Seen by the tracker, but outside this camera's image or behind it: not reported.
        if (!(depth > 0.0) ||
            !(uv.x >= 0.0 && uv.x < cam.width_px && uv.y >= 0.0 && uv.y < cam.height_px)) {
          continue;
        }
        out.push_back({feature_ids[c][i], static_cast<float>(uv.x), static_cast<float>(uv.y),
                       static_cast<float>(depth)});
      }
    }
    pose.has_features = true;
  }

  vit_result_t start() {
    if (push.load() != nullptr) return VIT_SUCCESS;  // already running
    if (!camera_given[0] || !camera_given[1]) {
      vit_log(
          "start: no calibration for camera %d (vit_tracker_add_camera_calibration or a "
          "rig file in vit_config_t.file)",
          camera_given[0] ? 1 : 0);
      return VIT_ERROR_INVALID_VALUE;
    }
    wallar::firmware::PushModuleOptions po;
    const double rate_hz = std::max(rig.cams[0].rate_hz, rig.cams[1].rate_hz);
    // The replay's pairing tolerance: half a frame period (5 ms when the rate is unknown).
    po.pair_tolerance_ns =
        rate_hz > 0.0 ? static_cast<DurationNs>(0.5e9 / rate_hz) : 5 * wallar::kNsPerMs;
    po.imu = imu_given;
    modules.push_back(std::make_unique<wallar::firmware::PushModule>(po));
    wallar::firmware::PushModule& module = *modules.back();
    stop.store(false);
    reset_requested.store(false);
    worker_done.store(false);
    forget_last.store(true);
    worker_error.clear();
    sequence = {0, 0};
    worker = std::thread([this, &module] {
      wallar::firmware::ApplianceOptions options =
          wallar::firmware::offline_options(wallar::firmware::ApplianceMode::kLockStep);
      options.on_frame_pose = [this](const wallar::firmware::FramePose& f) { on_frame_pose(f); };
      options.test_input = [this](TimeNs) {
        return reset_requested.exchange(false) ? wallar::drivers::InputAction::kReset
                                               : wallar::drivers::InputAction::kNone;
      };
      try {
        wallar::firmware::run_over_source(rig, rig_source, module, wallar::firmware::BoardConfig{},
                                          options, stop);
      } catch (const std::exception& e) {
        worker_error = e.what();
      } catch (...) {
        worker_error = "unknown error";
      }
      worker_done.store(true, std::memory_order_release);
    });
    // The modules are built (the calibration accepted) once the source is started.
    while (!module.started() && !worker_done.load(std::memory_order_acquire)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (!module.started()) {
      worker.join();
      vit_log("start: %s", worker_error.c_str());
      return VIT_ERROR_INVALID_VALUE;
    }
    push.store(&module, std::memory_order_release);
    return VIT_SUCCESS;
  }

  vit_result_t stop_running() {
    wallar::firmware::PushModule* module = push.exchange(nullptr);
    if (module == nullptr) return VIT_SUCCESS;
    module->end_of_stream();  // what was pushed is tracked, then the run ends
    worker.join();
    if (!worker_error.empty())
      vit_log("the tracker stopped with an error: %s", worker_error.c_str());
    {
      const std::lock_guard lock(poses_mutex);
      if (poses_dropped > 0) {
        vit_log("%llu poses dropped: not popped while %zu were queued",
                static_cast<unsigned long long>(poses_dropped), kMaxQueuedPoses);
      }
    }
    const wallar::firmware::PushCounters c = module->counters();
    if (c.imu_full + c.images_full + c.imu_out_of_order + c.images_out_of_order > 0) {
      vit_log(
          "refused: %llu IMU samples (queue full), %llu images (queue full), %llu IMU and "
          "%llu images out of order",
          static_cast<unsigned long long>(c.imu_full),
          static_cast<unsigned long long>(c.images_full),
          static_cast<unsigned long long>(c.imu_out_of_order),
          static_cast<unsigned long long>(c.images_out_of_order));
    }
    return VIT_SUCCESS;
  }
};

namespace {

vit_result_t result_of(wallar::firmware::PushResult r) {
  switch (r) {
    case wallar::firmware::PushResult::kAccepted:
      return VIT_SUCCESS;
    case wallar::firmware::PushResult::kFull:
      return VIT_ERROR_ALLOCATION_FAILURE;
    case wallar::firmware::PushResult::kOutOfOrder:
    case wallar::firmware::PushResult::kClosed:
      return VIT_ERROR_INVALID_VALUE;
  }
  return VIT_ERROR_INVALID_VALUE;
}

}  // namespace

WALLAR_VIT_EXPORT vit_result_t vit_api_get_version(uint32_t* out_major, uint32_t* out_minor,
                                                   uint32_t* out_patch) {
  if (out_major == nullptr || out_minor == nullptr || out_patch == nullptr) {
    return VIT_ERROR_INVALID_VALUE;
  }
  *out_major = VIT_HEADER_VERSION_MAJOR;
  *out_minor = VIT_HEADER_VERSION_MINOR;
  *out_patch = VIT_HEADER_VERSION_PATCH;
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_create(const vit_config_t* config,
                                                  vit_tracker_t** out_tracker) {
  if (out_tracker == nullptr) return VIT_ERROR_INVALID_VALUE;
  *out_tracker = nullptr;
  if (config == nullptr) {
    vit_log("create: no config");
    return VIT_ERROR_INVALID_VALUE;
  }
  // Monado leaves the count at 0 when its SLAM_CAM_COUNT is unset: 0 means the default, two.
  if (config->cam_count != 0 && config->cam_count != 2) {
    vit_log("create: cam_count %u: the tracker is stereo (2 cameras)", config->cam_count);
    return VIT_ERROR_INVALID_VALUE;
  }
  if (config->imu_count > 1) {
    vit_log("create: imu_count %u: one IMU at most", config->imu_count);
    return VIT_ERROR_INVALID_VALUE;
  }
  auto* t = new (std::nothrow) vit_tracker;
  if (t == nullptr) return VIT_ERROR_ALLOCATION_FAILURE;
  if (config->file != nullptr && config->file[0] != '\0') {
    try {
      t->rig = wallar::recording::read_rig_calibration(config->file);
      t->rig_source = config->file;
      t->camera_given = {true, true};
      t->imu_given = t->rig.imu_extrinsic_known && t->rig.imu.rate_hz > 0.0;
    } catch (const std::exception& e) {
      vit_log("create: %s", e.what());
      delete t;
      return VIT_ERROR_INVALID_VALUE;
    }
  }
  *out_tracker = t;
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT void vit_tracker_destroy(vit_tracker_t* tracker) {
  if (tracker == nullptr) return;
  if (tracker->push.exchange(nullptr) != nullptr) {
    tracker->stop.store(true);  // no drain: the run ends now
    tracker->worker.join();
  }
  delete tracker;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_has_image_format(const vit_tracker_t* tracker,
                                                            vit_image_format_t image_format,
                                                            bool* out_supported) {
  if (tracker == nullptr || out_supported == nullptr) return VIT_ERROR_INVALID_VALUE;
  *out_supported = raw_enum(image_format) == VIT_IMAGE_FORMAT_L8;
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_get_supported_extensions(
    const vit_tracker_t* tracker, vit_tracker_extension_set_t* out_exts) {
  if (tracker == nullptr || out_exts == nullptr) return VIT_ERROR_INVALID_VALUE;
  *out_exts = {true, true, true, true};
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_get_enabled_extensions(
    const vit_tracker_t* tracker, vit_tracker_extension_set_t* out_exts) {
  if (tracker == nullptr || out_exts == nullptr) return VIT_ERROR_INVALID_VALUE;
  // The calibration calls are always available.
  *out_exts = {true, true, tracker->timing_enabled.load(), tracker->features_enabled.load()};
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_enable_extension(vit_tracker_t* tracker,
                                                            vit_tracker_extension_t ext,
                                                            bool enable) {
  if (tracker == nullptr) return VIT_ERROR_INVALID_VALUE;
  switch (raw_enum(ext)) {
    case VIT_TRACKER_EXTENSION_ADD_CAMERA_CALIBRATION:
    case VIT_TRACKER_EXTENSION_ADD_IMU_CALIBRATION:
      return enable ? VIT_SUCCESS : VIT_ERROR_NOT_SUPPORTED;  // always on
    case VIT_TRACKER_EXTENSION_POSE_TIMING:
      tracker->timing_enabled.store(enable);
      return VIT_SUCCESS;
    case VIT_TRACKER_EXTENSION_POSE_FEATURES:
      tracker->features_enabled.store(enable);
      return VIT_SUCCESS;
    case VIT_TRACKER_EXTENSION_COUNT:
      break;
  }
  return VIT_ERROR_INVALID_VALUE;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_start(vit_tracker_t* tracker) {
  if (tracker == nullptr) return VIT_ERROR_INVALID_VALUE;
  return tracker->start();
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_stop(vit_tracker_t* tracker) {
  if (tracker == nullptr) return VIT_ERROR_INVALID_VALUE;
  return tracker->stop_running();
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_reset(vit_tracker_t* tracker) {
  if (tracker == nullptr) return VIT_ERROR_INVALID_VALUE;
  if (tracker->push.load() != nullptr) {
    tracker->reset_requested.store(true);  // the supervisor's next tick resets tracking
  }
  tracker->forget_last.store(true);
  tracker->clear_poses();
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_is_running(const vit_tracker_t* tracker,
                                                      bool* out_bool) {
  if (tracker == nullptr || out_bool == nullptr) return VIT_ERROR_INVALID_VALUE;
  *out_bool = tracker->push.load() != nullptr && !tracker->worker_done.load();
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_push_imu_sample(vit_tracker_t* tracker,
                                                           const vit_imu_sample_t* sample) {
  if (tracker == nullptr || sample == nullptr) return VIT_ERROR_INVALID_VALUE;
  wallar::firmware::PushModule* module = tracker->push.load(std::memory_order_acquire);
  if (module == nullptr) return VIT_ERROR_INVALID_VALUE;    // not started
  if (!tracker->imu_given) return VIT_ERROR_INVALID_VALUE;  // no IMU calibration: vision only
  const Eigen::Vector3d a(sample->ax, sample->ay, sample->az);
  const Eigen::Vector3d w(sample->wx, sample->wy, sample->wz);
  if (!a.allFinite() || !w.allFinite() || sample->timestamp <= 0) return VIT_ERROR_INVALID_VALUE;
  wallar::ImuSample s;
  s.t_ns = sample->timestamp;
  s.publish_t_ns = wallar::monotonic_now_ns();
  // The accelerometer's offset is the rig's bias (the modules subtract it); the rest here.
  s.accel_m_s2 = tracker->accel_transform * a;
  s.gyro_rad_s = tracker->gyro_transform * w + tracker->gyro_offset;
  return result_of(module->push_imu(s));
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_push_img_sample(vit_tracker_t* tracker,
                                                           const vit_img_sample_t* sample) {
  if (tracker == nullptr || sample == nullptr) return VIT_ERROR_INVALID_VALUE;
  wallar::firmware::PushModule* module = tracker->push.load(std::memory_order_acquire);
  if (module == nullptr) return VIT_ERROR_INVALID_VALUE;  // not started
  if (sample->cam_index > 1) return VIT_ERROR_INVALID_VALUE;
  if (raw_enum(sample->format) != VIT_IMAGE_FORMAT_L8) return VIT_ERROR_NOT_SUPPORTED;
  const wallar::CameraCalibration& cam = tracker->rig.cams[sample->cam_index];
  const std::uint64_t rows_bytes =
      sample->height == 0
          ? 0
          : static_cast<std::uint64_t>(sample->stride) * (sample->height - 1) + sample->width;
  if (sample->data == nullptr || sample->timestamp <= 0 ||
      static_cast<int>(sample->width) != cam.width_px ||
      static_cast<int>(sample->height) != cam.height_px || sample->stride < sample->width ||
      (sample->size != 0 && sample->size < rows_bytes)) {
    return VIT_ERROR_INVALID_VALUE;
  }
  wallar::CameraFrame frame;
  frame.t_ns = sample->timestamp;
  frame.sequence = tracker->sequence[sample->cam_index]++;
  frame.image = wallar::Image::allocate(cam.width_px, cam.height_px, wallar::PixelFormat::kGray8);
  for (int y = 0; y < cam.height_px; ++y) {
    std::memcpy(
        frame.image.mutable_data() + static_cast<std::ptrdiff_t>(y) * frame.image.stride_bytes(),
        sample->data + static_cast<std::size_t>(y) * sample->stride, sample->width);
  }
  frame.publish_t_ns = wallar::monotonic_now_ns();
  return result_of(module->push_image(static_cast<int>(sample->cam_index), std::move(frame)));
}

WALLAR_VIT_EXPORT vit_result_t
vit_tracker_add_imu_calibration(vit_tracker_t* tracker, const vit_imu_calibration_t* calibration) {
  if (tracker == nullptr || calibration == nullptr) return VIT_ERROR_INVALID_VALUE;
  if (tracker->push.load() != nullptr) {
    vit_log("add_imu_calibration: the tracker is running");
    return VIT_ERROR_INVALID_VALUE;
  }
  const vit_imu_calibration_t& c = *calibration;
  const vit_inertial_calibration_t* sensors[] = {&c.accel, &c.gyro};
  bool ok = c.imu_index == 0 && std::isfinite(c.frequency) && c.frequency > 0.0;
  for (const vit_inertial_calibration_t* s : sensors) {
    ok = ok && all_finite(s->transform, 9) && all_finite(s->offset, 3) &&
         all_finite(s->bias_std, 3) && all_finite(s->noise_std, 3);
    for (int i = 0; ok && i < 3; ++i) ok = s->bias_std[i] >= 0.0 && s->noise_std[i] >= 0.0;
    ok = ok && std::abs(matrix3_of(s->transform).determinant()) > 1e-6;
  }
  if (!ok) {
    vit_log(
        "add_imu_calibration: IMU %u: needs index 0, a rate > 0, finite non-negative noise "
        "and an invertible transform",
        c.imu_index);
    return VIT_ERROR_INVALID_VALUE;
  }
  wallar::ImuCalibration& imu = tracker->rig.imu;
  imu.rate_hz = c.frequency;
  // Per axis in the interface; wallar's filter takes one figure per sensor: the mean.
  imu.accel_noise_density = one_of_three(c.accel.noise_std);
  imu.accel_random_walk = one_of_three(c.accel.bias_std);
  imu.gyro_noise_density = one_of_three(c.gyro.noise_std);
  imu.gyro_random_walk = one_of_three(c.gyro.bias_std);
  // calibrated = transform * raw + offset: the accelerometer's offset is the rig's bias.
  imu.accel_bias_m_s2 = -Eigen::Vector3d(c.accel.offset[0], c.accel.offset[1], c.accel.offset[2]);
  imu.T_body_imu = wallar::SE3d::Identity();  // body = IMU: the cameras are given against it
  tracker->accel_transform = matrix3_of(c.accel.transform);
  tracker->gyro_transform = matrix3_of(c.gyro.transform);
  tracker->gyro_offset = Eigen::Vector3d(c.gyro.offset[0], c.gyro.offset[1], c.gyro.offset[2]);
  tracker->rig.imu_extrinsic_known = true;
  tracker->imu_given = true;
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_add_camera_calibration(
    vit_tracker_t* tracker, const vit_camera_calibration_t* calibration) {
  if (tracker == nullptr || calibration == nullptr) return VIT_ERROR_INVALID_VALUE;
  if (tracker->push.load() != nullptr) {
    vit_log("add_camera_calibration: the tracker is running");
    return VIT_ERROR_INVALID_VALUE;
  }
  const vit_camera_calibration_t& c = *calibration;
  const unsigned index = c.camera_index;
  std::size_t coefficients = 0;
  const int model = raw_enum(c.model);
  switch (model) {
    case VIT_CAMERA_DISTORTION_NONE:
      coefficients = 0;
      break;
    case VIT_CAMERA_DISTORTION_RT4:
      coefficients = 4;
      break;
    case VIT_CAMERA_DISTORTION_RT5:
      coefficients = 5;
      break;
    case VIT_CAMERA_DISTORTION_RT8:
      coefficients = 8;  // OpenCV's rational model, which the rectifier takes as it is
      break;
    case VIT_CAMERA_DISTORTION_KB4:
      vit_log(
          "add_camera_calibration: camera %u: Kannala-Brandt (KB4) is not supported: the "
          "tracker rectifies radial-tangential cameras only",
          index);
      return VIT_ERROR_NOT_SUPPORTED;
    default:
      vit_log("add_camera_calibration: camera %u: unknown distortion model %d", index, model);
      return VIT_ERROR_INVALID_VALUE;
  }
  const double intrinsics[] = {c.frequency, c.fx, c.fy, c.cx, c.cy};
  bool ok = index < 2 && c.width > 0 && c.height > 0 && all_finite(intrinsics, 5) &&
            c.frequency >= 0.0 && c.fx > 0.0 && c.fy > 0.0 && c.distortion_count >= coefficients &&
            c.distortion_count <= VIT_CAMERA_CALIBRATION_DISTORTION_MAX_COUNT &&
            all_finite(c.distortion, coefficients) && all_finite(c.transform, 16);
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  if (ok) {
    for (int r = 0; r < 4; ++r) {
      for (int col = 0; col < 4; ++col) T(r, col) = c.transform[r * 4 + col];
    }
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    ok = T.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-9) &&
         (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-4 && R.determinant() > 0;
  }
  if (!ok) {
    vit_log(
        "add_camera_calibration: camera %u: needs index 0 or 1, a size, finite intrinsics "
        "with focal lengths > 0, the model's %zu distortion coefficients and a rigid "
        "T_imu_cam",
        index, coefficients);
    return VIT_ERROR_INVALID_VALUE;
  }
  wallar::CameraCalibration& cam = tracker->rig.cams[index];
  cam.name = index == 0 ? "cam0" : "cam1";
  cam.width_px = c.width;
  cam.height_px = c.height;
  cam.rate_hz = c.frequency;
  cam.fx = c.fx;
  cam.fy = c.fy;
  cam.cx = c.cx;
  cam.cy = c.cy;
  cam.distortion_model = "radial-tangential";
  cam.distortion.assign(std::max<std::size_t>(coefficients, 4), 0.0);
  for (std::size_t i = 0; i < coefficients; ++i) cam.distortion[i] = c.distortion[i];
  cam.T_body_cam = wallar::SE3d::Identity();
  cam.T_body_cam.linear() = T.topLeftCorner<3, 3>();
  cam.T_body_cam.translation() = T.topRightCorner<3, 1>();
  tracker->camera_given[index] = true;
  if (tracker->rig_source.find("VIT") == std::string::npos) {
    tracker->rig_source += " with the VIT calibration calls";  // a file's, overridden
  }
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_tracker_pop_pose(vit_tracker_t* tracker, vit_pose_t** out_pose) {
  if (tracker == nullptr) return VIT_ERROR_INVALID_VALUE;
  vit_pose* pose = nullptr;
  {
    const std::lock_guard lock(tracker->poses_mutex);
    if (!tracker->poses.empty()) {
      pose = tracker->poses.front();
      tracker->poses.pop_front();
    }
  }
  if (out_pose == nullptr) {
    delete pose;
  } else {
    *out_pose = pose;
  }
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t
vit_tracker_get_timing_titles(const vit_tracker_t* tracker, vit_tracker_timing_titles* out_titles) {
  if (tracker == nullptr || out_titles == nullptr) return VIT_ERROR_INVALID_VALUE;
  out_titles->count = static_cast<uint32_t>(kTimingTitles.size());
  out_titles->titles = const_cast<const char**>(kTimingTitles.data());
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT void vit_pose_destroy(vit_pose_t* pose) { delete pose; }

WALLAR_VIT_EXPORT vit_result_t vit_pose_get_data(const vit_pose_t* pose,
                                                 vit_pose_data_t* out_data) {
  if (pose == nullptr || out_data == nullptr) return VIT_ERROR_INVALID_VALUE;
  *out_data = pose->data;
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_pose_get_timing(const vit_pose_t* pose,
                                                   vit_pose_timing_t* out_timing) {
  if (pose == nullptr || out_timing == nullptr) return VIT_ERROR_INVALID_VALUE;
  if (!pose->has_timing) return VIT_ERROR_NOT_ENABLED;
  out_timing->count = static_cast<uint32_t>(pose->timing.size());
  out_timing->timestamps = pose->timing.data();
  return VIT_SUCCESS;
}

WALLAR_VIT_EXPORT vit_result_t vit_pose_get_features(const vit_pose_t* pose, uint32_t camera_index,
                                                     vit_pose_features_t* out_features) {
  if (pose == nullptr || out_features == nullptr || camera_index > 1) {
    return VIT_ERROR_INVALID_VALUE;
  }
  if (!pose->has_features) return VIT_ERROR_NOT_ENABLED;
  const std::vector<vit_pose_feature_t>& f = pose->features[camera_index];
  out_features->count = static_cast<uint32_t>(f.size());
  out_features->features = f.data();
  return VIT_SUCCESS;
}
