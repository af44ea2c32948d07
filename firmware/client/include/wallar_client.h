/* SPDX-License-Identifier: Apache-2.0 */
/**
 * @file wallar_client.h
 * @brief libwallar-client: the head pose and the room's planes of a running `wallar run`, for
 * applications (C ABI, libwallar-client.so.0; pkg-config wallar-client).
 *
 * The firmware serves a UNIX stream socket (board `client:`, `wallar run --client-socket`;
 * /run/wallar/client.sock, mode 0660, group wallar on a headset). connect() negotiates the
 * protocol version (a mismatch fails with the firmware's one-line message) and receives a
 * shared-memory block the firmware updates with each pose and each IMU sample after it:
 * wallar_client_locate() predicts the pose at any time from it without a round trip, as an
 * OpenXR runtime answers xrLocateSpace for a display time. Planes (OpenXR semantics: a stable
 * id, a pose whose +z is the normal toward the viewer, extents, a counter-clockwise polygon,
 * orientation, semantic label, a change counter, subsumed-by on merges) arrive as events; a
 * planes snapshot (begin/get/end) is a consistent copy of the whole set.
 *
 * Frames and time: world = the firmware's (its first body pose, as the run's files), body =
 * the headset's IMU frame; times are int64 nanoseconds of the sensors' clock (CLOCK_MONOTONIC
 * on a headset; a replay's recording clock, see wallar_client_now_ns()).
 *
 * Threading: a wallar_client is used by one thread at a time (poll_events, begin_planes,
 * disconnect), except wallar_client_locate() and wallar_client_now_ns(), which any number of
 * threads may call at once and alongside the others (they only read shared memory; never
 * block, never allocate). A wallar_planes snapshot is immutable: any thread may read it; it
 * is independent of the client and is released once with wallar_planes_end().
 */
#ifndef WALLAR_CLIENT_H
#define WALLAR_CLIENT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define WALLAR_CLIENT_API __attribute__((visibility("default")))

/** The protocol this library speaks (the firmware refuses another, with a message). */
#define WALLAR_CLIENT_PROTOCOL_VERSION 1

typedef struct wallar_client wallar_client;
typedef struct wallar_planes wallar_planes;

typedef enum wallar_tracking {
  WALLAR_TRACKING_NONE = 0, /**< no pose yet */
  WALLAR_TRACKING_INITIALISING = 1,
  WALLAR_TRACKING_TRACKING = 2,
  WALLAR_TRACKING_LOST = 3 /**< the pose held, relocalising */
} wallar_tracking;

/** As XrSpaceLocationFlags. */
enum {
  WALLAR_POSE_ORIENTATION_VALID = 1,
  WALLAR_POSE_POSITION_VALID = 2,
  WALLAR_POSE_ORIENTATION_TRACKED = 4,
  WALLAR_POSE_POSITION_TRACKED = 8
};

typedef struct wallar_pose {
  int64_t t_ns;                /**< the time asked for */
  double q_world_body_xyzw[4]; /**< rotation body -> world */
  double p_world_body_m[3];    /**< the body's origin in the world */
  uint32_t flags;              /**< WALLAR_POSE_* */
  int32_t tracking;            /**< wallar_tracking */
  int64_t t_pose_ns;           /**< the newest tracked pose it was predicted from */
  int64_t t_imu_ns;            /**< the newest IMU sample integrated since */
  uint32_t epoch;              /**< +1 at each reset of the firmware's map */
} wallar_pose;

typedef enum wallar_plane_orientation {
  WALLAR_ORIENTATION_HORIZONTAL_UPWARD = 0,
  WALLAR_ORIENTATION_HORIZONTAL_DOWNWARD = 1,
  WALLAR_ORIENTATION_VERTICAL = 2,
  WALLAR_ORIENTATION_ARBITRARY = 3
} wallar_plane_orientation;

typedef enum wallar_plane_label {
  WALLAR_LABEL_UNKNOWN = 0,
  WALLAR_LABEL_FLOOR = 1,
  WALLAR_LABEL_WALL = 2,
  WALLAR_LABEL_CEILING = 3
} wallar_plane_label;

typedef struct wallar_plane {
  uint32_t id;                  /**< stable while the plane lives */
  int32_t orientation;          /**< wallar_plane_orientation */
  int32_t label;                /**< wallar_plane_label */
  uint64_t change_count;        /**< +1 whenever its geometry changed */
  double p_world_plane_m[3];    /**< the plane frame's origin: its polygon's box centre */
  double q_world_plane_xyzw[4]; /**< the plane frame: +z the normal toward the viewer */
  double extent_m[2];           /**< width along x, height along y */
  uint32_t vertex_count;        /**< the polygon's (wallar_planes_polygon) */
} wallar_plane;

typedef enum wallar_event_type {
  WALLAR_EVENT_PLANE_ADDED = 1,
  WALLAR_EVENT_PLANE_UPDATED = 2,
  WALLAR_EVENT_PLANE_REMOVED = 3, /**< subsumed_by: the plane that absorbed it, or 0 */
  WALLAR_EVENT_TRACKING_CHANGED = 4,
  WALLAR_EVENT_DISCONNECTED = 5 /**< the firmware closed the connection (it stopped) */
} wallar_event_type;

typedef struct wallar_event {
  int32_t type;           /**< wallar_event_type */
  uint32_t plane_id;      /**< PLANE_* events */
  uint32_t subsumed_by;   /**< PLANE_REMOVED: the absorbing plane's id (0: none) */
  int32_t tracking;       /**< TRACKING_CHANGED: the new wallar_tracking */
  int64_t t_ns;           /**< the sensor time of the change */
  uint64_t model_version; /**< PLANE_*: the firmware's wall model it came with */
} wallar_event;

/**
 * Connects to the firmware's socket at `path` and negotiates the protocol. On success returns
 * 0 and sets *out. On failure returns -1 and writes a one-line reason into `error` (the
 * firmware's message on a version mismatch or a refusal; may be NULL).
 */
WALLAR_CLIENT_API int wallar_client_connect(const char* path, const char* app_name,
                                            wallar_client** out, char* error, size_t error_size);
/** Closes the connection and frees the client (NULL is fine). */
WALLAR_CLIENT_API void wallar_client_disconnect(wallar_client* client);
/** The socket: readable when events are waiting (for the application's own poll()). */
WALLAR_CLIENT_API int wallar_client_fd(const wallar_client* client);
/** The sensors' clock now (CLOCK_MONOTONIC, mapped to a replay's clock during a replay). */
WALLAR_CLIENT_API int64_t wallar_client_now_ns(const wallar_client* client);
/**
 * The body's pose predicted at `t_ns` from the newest pose, the IMU's rotation since and the
 * velocity. Returns 0 (flags say what is valid: nothing before the first pose), -1 if the
 * shared memory never gave a consistent read (a writer dead mid-store).
 */
WALLAR_CLIENT_API int wallar_client_locate(const wallar_client* client, int64_t t_ns,
                                           wallar_pose* out);
/**
 * The view an app renders from, in the body frame (T_body_view): the headset's rectified left
 * camera, the video see-through eye (x right, y down, z forward, as OpenCV's cameras). The
 * eye's pose at a time is the located body pose times this. Constant for a run. Returns 0, or
 * -1 if the shared memory never gave a consistent read.
 */
WALLAR_CLIENT_API int wallar_client_view(const wallar_client* client, double q_body_view_xyzw[4],
                                         double p_body_view_m[3]);
/**
 * Reads what arrived (waiting up to `timeout_ms` when nothing has: 0 never waits, -1 waits
 * for ever) and returns up to `max` events (>= 0). After the firmware closed the connection,
 * one WALLAR_EVENT_DISCONNECTED and then -1.
 */
WALLAR_CLIENT_API int wallar_client_poll_events(wallar_client* client, int timeout_ms,
                                                wallar_event* events, int max);
/** The tracking state as last reported on the socket (wallar_tracking). */
WALLAR_CLIENT_API int32_t wallar_client_tracking(const wallar_client* client);

/** A consistent snapshot of every plane as of the events read so far (0, or -1: no memory). */
WALLAR_CLIENT_API int wallar_client_begin_planes(wallar_client* client, wallar_planes** out);
WALLAR_CLIENT_API size_t wallar_planes_count(const wallar_planes* planes);
/** The firmware's wall model the snapshot is of (0: none yet). */
WALLAR_CLIENT_API uint64_t wallar_planes_model_version(const wallar_planes* planes);
/** Plane `index` (< count): 0, or -1 for an index out of range. */
WALLAR_CLIENT_API int wallar_planes_get(const wallar_planes* planes, size_t index,
                                        wallar_plane* out);
/**
 * Plane `index`'s polygon in its plane frame (x, y pairs, metres, counter-clockwise seen from
 * +z): copies up to `capacity` vertices into xy (2 * capacity doubles) and returns the
 * vertex count (0 for an index out of range).
 */
WALLAR_CLIENT_API size_t wallar_planes_polygon(const wallar_planes* planes, size_t index,
                                               double* xy, size_t capacity);
WALLAR_CLIENT_API void wallar_planes_end(wallar_planes* planes);

#ifdef __cplusplus
}
#endif

#endif /* WALLAR_CLIENT_H */
