/* SPDX-License-Identifier: Apache-2.0 */
/**
 * @file wallar_vit.h
 * @brief libwallar_vit.so: wallar's tracker behind the Visual-Inertial Tracking (VIT) interface
 * that Monado loads external trackers through (VIT_SYSTEM_LIBRARY_PATH), interface version
 * 2.0.1. These are wallar's own declarations, written from the interface's documentation; the
 * types, their layout and the function signatures are the interface's, so a consumer built
 * against Monado's vit_interface.h calls this library unchanged (tests/vit checks every
 * symbol the way Monado's loader resolves them).
 *
 * What the library runs: the appliance's own modules (firmware/appliance.hpp) in lock step,
 * the same attitude filter, tracker and mapping as `wallar track --lockstep`, fed by a push
 * source (firmware/appliance/push_module.hpp) instead of a recording.
 *
 * Poses: T_world_imu, the IMU (body) frame in the world of the first body pose (the world of
 * `wallar track`'s trajectory files: not gravity-aligned), position [m] and unit quaternion,
 * one per stereo frame the tracker tracked, time-stamped with the frame's time; velocity is the
 * finite difference of the last two poses [m/s]. Frames that are not tracked (initialising,
 * lost) give no pose.
 *
 * Pose features (VIT_TRACKER_EXTENSION_POSE_FEATURES, off until enabled): per camera, the map
 * points the tracker tracked in that frame (its pose's inliers and a key-frame's new points)
 * where that camera saw them, in the pixels of the images pushed (the tracker measures in
 * rectified images; each observation is taken back through its camera's rectification and
 * distortion), with the point's depth along that camera's axis [m]. id names one map point
 * in every pose that sees it (the low 32 bits its slot in the map, the high 32 the slot's
 * generation, so a slot reused for a new point gives a new id). The right camera lists the
 * points it matched; a point outside a camera's raw image is left out.
 *
 * Threading contract (the interface's, and what this library adds):
 *  - vit_tracker_push_imu_sample() from one thread, vit_tracker_push_img_sample() from one
 *    thread (may be another), each with increasing time stamps; neither waits for the
 *    tracker: a sample goes into a lock-free bounded queue (IMU 4096, images 16; an image is
 *    first copied into a buffer of its own, the one allocation) and the tracker's threads take
 *    it from there. A full queue refuses the sample with VIT_ERROR_ALLOCATION_FAILURE
 *    (counted; the caller may drop it or push it again); an out-of-order, non-finite or
 *    wrongly sized sample, or one before start or after stop, with VIT_ERROR_INVALID_VALUE.
 *  - vit_tracker_pop_pose() from one consumer thread, non-blocking (a short lock).
 *  - create, destroy, start, stop, reset, the calibration and extension calls from one
 *    control thread, never concurrently with each other; calibrations and extensions before
 *    start. stop() waits until every sample pushed before it was tracked, then stops the
 *    threads; poses produced until then stay poppable until reset() or destroy().
 *  - A pose and what it points to live until vit_pose_destroy(); poses may be destroyed from
 *    any thread.
 *
 * Calibration: two cameras (pinhole, VIT_CAMERA_DISTORTION_NONE, _RT4, _RT5 or _RT8, OpenCV's
 * radial-tangential models, which the tracker's rectifier takes; _KB4 fisheyes are refused
 * with VIT_ERROR_NOT_SUPPORTED) with T_imu_cam, of one image size, and one IMU (its
 * accelerometer offset becomes the rig's bias, the transforms and the gyro offset are applied
 * to each sample, the per-axis noise figures are averaged); or vit_config_t.file naming a rig
 * calibration wallar reads (a EuRoC folder, a Kalibr camchain or wallar rig YAML, an OpenCV
 * stereo YAML), which calibration calls then override. Bad input gives a VIT error result and a
 * line on stderr, never a crash.
 */
#ifndef WALLAR_VIT_H
#define WALLAR_VIT_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The interface version this library implements; consumers check the major number. */
#define VIT_HEADER_VERSION_MAJOR 2
#define VIT_HEADER_VERSION_MINOR 0
#define VIT_HEADER_VERSION_PATCH 1

#define VIT_CAMERA_CALIBRATION_DISTORTION_MAX_COUNT 32

/* 0 is success, negative values are errors. */
typedef enum vit_result {
  VIT_SUCCESS = 0,
  VIT_ERROR_INVALID_VERSION = -1,
  VIT_ERROR_INVALID_VALUE = -2,
  VIT_ERROR_ALLOCATION_FAILURE = -3,
  VIT_ERROR_NOT_SUPPORTED = -4,
  VIT_ERROR_NOT_ENABLED = -5,
} vit_result_t;

typedef enum vit_image_format {
  VIT_IMAGE_FORMAT_L8 = 1,     /* 8-bit gray: the one this library takes */
  VIT_IMAGE_FORMAT_L16 = 2,    /* 16-bit gray */
  VIT_IMAGE_FORMAT_R8G8B8 = 3, /* packed 24-bit RGB */
} vit_image_format_t;

typedef enum vit_camera_distortion {
  VIT_CAMERA_DISTORTION_NONE, /* already undistorted */
  VIT_CAMERA_DISTORTION_RT4,  /* radial-tangential k1 k2 p1 p2 */
  VIT_CAMERA_DISTORTION_RT5,  /* radial-tangential k1 k2 p1 p2 k3 */
  VIT_CAMERA_DISTORTION_RT8,  /* rational radial-tangential, 8 parameters */
  VIT_CAMERA_DISTORTION_KB4,  /* Kannala-Brandt (equidistant fisheye) k1..k4 */
} vit_camera_distortion_t;

typedef enum vit_tracker_extension {
  VIT_TRACKER_EXTENSION_ADD_CAMERA_CALIBRATION,
  VIT_TRACKER_EXTENSION_ADD_IMU_CALIBRATION,
  VIT_TRACKER_EXTENSION_POSE_TIMING,
  VIT_TRACKER_EXTENSION_POSE_FEATURES,
  VIT_TRACKER_EXTENSION_COUNT,
} vit_tracker_extension_t;

/* One flag per extension, in the order of vit_tracker_extension. */
typedef struct vit_tracker_extension_set {
  bool has_add_camera_calibration;
  bool has_add_imu_calibration;
  bool has_pose_timing;
  bool has_pose_features;
} vit_tracker_extension_set_t;

typedef struct vit_tracker vit_tracker_t; /* opaque */
typedef struct vit_pose vit_pose_t;       /* opaque */

/* The names of the time stamps vit_pose_get_timing() returns, in order. */
typedef struct vit_tracker_timing_titles {
  uint32_t count;
  const char **titles;
} vit_tracker_timing_titles;

typedef struct vit_config {
  const char *file;   /* implementation-specific file (here: a rig calibration), or NULL */
  uint32_t cam_count; /* cameras (here: 2) */
  uint32_t imu_count; /* IMUs (0 or 1) */
  bool show_ui;       /* ignored: the library has no window */
} vit_config_t;

typedef struct vit_imu_sample {
  int64_t timestamp; /* [ns] */
  float ax, ay, az;  /* specific force [m/s^2] */
  float wx, wy, wz;  /* angular rate [rad/s] */
} vit_imu_sample_t;

typedef struct vit_mask {
  float x, y, w, h; /* [px] */
} vit_mask_t;

typedef struct vit_img_sample {
  uint32_t cam_index; /* 0 left, 1 right */
  int64_t timestamp;  /* [ns], increasing per camera; a stereo pair shares one */
  uint8_t *data;
  uint32_t width, height;
  uint32_t stride, size; /* bytes per row, bytes in all */
  vit_image_format_t format;
  uint32_t mask_count; /* regions to ignore (this library does not use them) */
  vit_mask_t *masks;
} vit_img_sample_t;

typedef struct vit_pose_data {
  int64_t timestamp;    /* [ns] */
  float px, py, pz;     /* position [m] */
  float ox, oy, oz, ow; /* orientation quaternion */
  float vx, vy, vz;     /* linear velocity [m/s] */
} vit_pose_data_t;

typedef struct vit_pose_timing {
  uint32_t count;
  const int64_t *timestamps; /* [ns], one per title */
} vit_pose_timing_t;

typedef struct vit_pose_feature {
  int64_t id;      /* the map point's, stable while it lives */
  float u, v;      /* [px] in the camera's pushed image */
  float depth;     /* [m] along the camera's axis */
} vit_pose_feature_t;

typedef struct vit_pose_features {
  uint32_t count;
  const struct vit_pose_feature *features;
} vit_pose_features_t;

/* A pinhole camera with an optional distortion model. */
typedef struct vit_camera_calibration {
  uint32_t camera_index; /* 0 left, 1 right */
  int width, height;     /* [px] */
  double frequency;      /* frames per second */
  double fx, fy;         /* focal lengths [px] */
  double cx, cy;         /* principal point [px] */
  enum vit_camera_distortion model;
  uint32_t distortion_count;
  double distortion[VIT_CAMERA_CALIBRATION_DISTORTION_MAX_COUNT];
  double transform[4 * 4]; /* T_imu_cam, row-major: camera coordinates into the IMU frame */
} vit_camera_calibration_t;

/* One inertial sensor: calibrated = transform * raw + offset. */
typedef struct vit_inertial_calibration {
  double transform[3 * 3]; /* row-major */
  double offset[3];
  double bias_std[3];  /* bias random walk sigma [U/sqrt(s^3)] (U = rad or m/s) */
  double noise_std[3]; /* white noise sigma [U/sqrt(s)] */
} vit_inertial_calibration_t;

typedef struct vit_imu_calibration {
  uint32_t imu_index; /* 0 */
  double frequency;   /* samples per second */
  struct vit_inertial_calibration accel;
  struct vit_inertial_calibration gyro;
} vit_imu_calibration_t;

/* The functions, as the loader resolves them by name with dlsym(). */
typedef vit_result_t (*PFN_vit_api_get_version)(uint32_t *out_major, uint32_t *out_minor,
                                                uint32_t *out_patch);
typedef vit_result_t (*PFN_vit_tracker_create)(const vit_config_t *config,
                                               vit_tracker_t **out_tracker);
typedef void (*PFN_vit_tracker_destroy)(vit_tracker_t *tracker);
typedef vit_result_t (*PFN_vit_tracker_has_image_format)(const vit_tracker_t *tracker,
                                                         vit_image_format_t image_format,
                                                         bool *out_supported);
typedef vit_result_t (*PFN_vit_tracker_get_supported_extensions)(
    const vit_tracker_t *tracker, vit_tracker_extension_set_t *out_exts);
typedef vit_result_t (*PFN_vit_tracker_get_enabled_extensions)(
    const vit_tracker_t *tracker, vit_tracker_extension_set_t *out_exts);
typedef vit_result_t (*PFN_vit_tracker_enable_extension)(vit_tracker_t *tracker,
                                                         vit_tracker_extension_t ext, bool enable);
typedef vit_result_t (*PFN_vit_tracker_start)(vit_tracker_t *tracker);
typedef vit_result_t (*PFN_vit_tracker_stop)(vit_tracker_t *tracker);
typedef vit_result_t (*PFN_vit_tracker_reset)(vit_tracker_t *tracker);
typedef vit_result_t (*PFN_vit_tracker_is_running)(const vit_tracker_t *tracker, bool *out_bool);
typedef vit_result_t (*PFN_vit_tracker_push_imu_sample)(vit_tracker_t *tracker,
                                                        const vit_imu_sample_t *sample);
typedef vit_result_t (*PFN_vit_tracker_push_img_sample)(vit_tracker_t *tracker,
                                                        const vit_img_sample_t *sample);
typedef vit_result_t (*PFN_vit_tracker_add_imu_calibration)(
    vit_tracker_t *tracker, const vit_imu_calibration_t *calibration);
typedef vit_result_t (*PFN_vit_tracker_add_camera_calibration)(
    vit_tracker_t *tracker, const vit_camera_calibration_t *calibration);
typedef vit_result_t (*PFN_vit_tracker_pop_pose)(vit_tracker_t *tracker, vit_pose_t **out_pose);
typedef vit_result_t (*PFN_vit_tracker_get_timing_titles)(const vit_tracker_t *tracker,
                                                          vit_tracker_timing_titles *out_titles);
typedef void (*PFN_vit_pose_destroy)(vit_pose_t *pose);
typedef vit_result_t (*PFN_vit_pose_get_data)(const vit_pose_t *pose, vit_pose_data_t *out_data);
typedef vit_result_t (*PFN_vit_pose_get_timing)(const vit_pose_t *pose,
                                                vit_pose_timing_t *out_timing);
typedef vit_result_t (*PFN_vit_pose_get_features)(const vit_pose_t *pose, uint32_t camera_index,
                                                  vit_pose_features_t *out_features);

#ifdef WALLAR_VIT_PROTOTYPES
vit_result_t vit_api_get_version(uint32_t *out_major, uint32_t *out_minor, uint32_t *out_patch);
vit_result_t vit_tracker_create(const vit_config_t *config, vit_tracker_t **out_tracker);
void vit_tracker_destroy(vit_tracker_t *tracker);
vit_result_t vit_tracker_has_image_format(const vit_tracker_t *tracker,
                                          vit_image_format_t image_format, bool *out_supported);
vit_result_t vit_tracker_get_supported_extensions(const vit_tracker_t *tracker,
                                                  vit_tracker_extension_set_t *out_exts);
vit_result_t vit_tracker_get_enabled_extensions(const vit_tracker_t *tracker,
                                                vit_tracker_extension_set_t *out_exts);
vit_result_t vit_tracker_enable_extension(vit_tracker_t *tracker, vit_tracker_extension_t ext,
                                          bool enable);
vit_result_t vit_tracker_start(vit_tracker_t *tracker);
vit_result_t vit_tracker_stop(vit_tracker_t *tracker);
vit_result_t vit_tracker_reset(vit_tracker_t *tracker);
vit_result_t vit_tracker_is_running(const vit_tracker_t *tracker, bool *out_bool);
vit_result_t vit_tracker_push_imu_sample(vit_tracker_t *tracker, const vit_imu_sample_t *sample);
vit_result_t vit_tracker_push_img_sample(vit_tracker_t *tracker, const vit_img_sample_t *sample);
vit_result_t vit_tracker_add_imu_calibration(vit_tracker_t *tracker,
                                             const vit_imu_calibration_t *calibration);
vit_result_t vit_tracker_add_camera_calibration(vit_tracker_t *tracker,
                                                const vit_camera_calibration_t *calibration);
vit_result_t vit_tracker_pop_pose(vit_tracker_t *tracker, vit_pose_t **out_pose);
vit_result_t vit_tracker_get_timing_titles(const vit_tracker_t *tracker,
                                           vit_tracker_timing_titles *out_titles);
void vit_pose_destroy(vit_pose_t *pose);
vit_result_t vit_pose_get_data(const vit_pose_t *pose, vit_pose_data_t *out_data);
vit_result_t vit_pose_get_timing(const vit_pose_t *pose, vit_pose_timing_t *out_timing);
vit_result_t vit_pose_get_features(const vit_pose_t *pose, uint32_t camera_index,
                                   vit_pose_features_t *out_features);
#endif

#ifdef __cplusplus
}
#endif

#endif /* WALLAR_VIT_H */
