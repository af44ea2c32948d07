/* SPDX-License-Identifier: Apache-2.0 */
/**
 * @file print_planes.c
 * @brief A minimal libwallar-client app: prints the head pose predicted for its own "display"
 * times (now + --ahead-ms, at --rate Hz) and the room's planes whenever they change, until the
 * firmware stops (or --duration passes).
 *
 *   print_planes --socket /run/wallar/client.sock [--rate 30] [--ahead-ms 16] [--wait 10]
 *
 * Output lines: "pose t_ns=... t_pose_ns=... p=x,y,z q=x,y,z,w flags=F tracking=T" (t_ns the
 * display time asked for, t_pose_ns the pose it was predicted from), "event ...", and per
 * change a snapshot: "snapshot model=V planes=N" then N lines "plane id=... label=...
 * orientation=... changes=... extent=W,H world=x,y,z;x,y,z;..." (the polygon in the world).
 *
 * Threading: one thread (the C API's contract for everything but locate()).
 */
#define _POSIX_C_SOURCE 200809L /* clock_gettime, nanosleep under -std=c11 (example_common.h) */

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "example_common.h"
#include "wallar_client.h"

static const char* orientation_name(int32_t o) {
  switch (o) {
    case WALLAR_ORIENTATION_HORIZONTAL_UPWARD:
      return "horizontal-upward";
    case WALLAR_ORIENTATION_HORIZONTAL_DOWNWARD:
      return "horizontal-downward";
    case WALLAR_ORIENTATION_VERTICAL:
      return "vertical";
    default:
      return "arbitrary";
  }
}

static void print_snapshot(wallar_client* c, const char* what) {
  wallar_planes* planes = NULL;
  if (wallar_client_begin_planes(c, &planes) != 0) return;
  const size_t n = wallar_planes_count(planes);
  printf("%s model=%llu planes=%zu\n", what,
         (unsigned long long)wallar_planes_model_version(planes), n);
  for (size_t i = 0; i < n; ++i) {
    wallar_plane p;
    if (wallar_planes_get(planes, i, &p) != 0) continue;
    double* xyz_world_m = example_polygon_world(planes, i, &p);
    if (xyz_world_m == NULL) break;
    printf("plane id=%u label=%s orientation=%s changes=%llu extent=%.4f,%.4f world=", p.id,
           example_label_name(p.label), orientation_name(p.orientation),
           (unsigned long long)p.change_count, p.extent_m[0], p.extent_m[1]);
    example_print_points(xyz_world_m, p.vertex_count);
    printf("\n");
    free(xyz_world_m);
  }
  wallar_planes_end(planes);
  fflush(stdout);
}

int main(int argc, char** argv) {
  example_options o = {"/run/wallar/client.sock", 30.0, 16.0, 10.0, 0.0};
  /* Options come in pairs: NAME VALUE. */
  for (int i = 1; i < argc; i += 2) {
    if (i + 1 >= argc || !example_option(&o, argv[i], argv[i + 1])) {
      fprintf(stderr,
              "usage: print_planes [--socket PATH] [--rate HZ] [--ahead-ms MS] [--wait S] "
              "[--duration S]\n");
      return 2;
    }
  }
  const char* socket_path = o.socket_path;
  const double rate_hz = o.rate_hz, ahead_ms = o.ahead_ms, duration_s = o.duration_s;
  if (!(rate_hz > 0.0 && rate_hz <= 1000.0)) {
    fprintf(stderr, "print_planes: error: --rate must be in (0, 1000] Hz\n");
    return 2;
  }
  wallar_client* c = example_connect(socket_path, "print_planes", o.wait_s);
  if (c == NULL) return 1;
  printf("connected %s\n", socket_path);
  /* Where to render from: the headset's eye (its rectified left camera) in the body frame. */
  double q_view[4], p_view[3];
  if (wallar_client_view(c, q_view, p_view) == 0) {
    printf("view in body: q_xyzw %.6f %.6f %.6f %.6f p %.6f %.6f %.6f m\n", q_view[0], q_view[1],
           q_view[2], q_view[3], p_view[0], p_view[1], p_view[2]);
  }
  fflush(stdout);
  const int64_t period_ns = (int64_t)(1e9 / rate_hz);
  const int64_t end_ns = duration_s > 0 ? example_monotonic_ns() + (int64_t)(duration_s * 1e9) : 0;
  int64_t next_ns = example_monotonic_ns();
  for (;;) {
    const int64_t now = example_monotonic_ns();
    if (end_ns != 0 && now >= end_ns) break;
    if (now >= next_ns) {
      /* A display frame: the pose at its (predicted) display time, in the sensors' clock. */
      wallar_pose pose;
      const int64_t t = wallar_client_now_ns(c) + (int64_t)(ahead_ms * 1e6);
      if (wallar_client_locate(c, t, &pose) == 0) {
        printf(
            "pose t_ns=%lld t_pose_ns=%lld p=%.5f,%.5f,%.5f q=%.6f,%.6f,%.6f,%.6f flags=%u "
            "tracking=%d\n",
            (long long)pose.t_ns, (long long)pose.t_pose_ns, pose.p_world_body_m[0],
            pose.p_world_body_m[1], pose.p_world_body_m[2], pose.q_world_body_xyzw[0],
            pose.q_world_body_xyzw[1], pose.q_world_body_xyzw[2], pose.q_world_body_xyzw[3],
            pose.flags, pose.tracking);
      }
      next_ns += period_ns;
      if (next_ns < now) next_ns = now + period_ns;
    }
    int timeout_ms = (int)((next_ns - example_monotonic_ns()) / 1000000);
    if (timeout_ms < 0) timeout_ms = 0;
    wallar_event events[64];
    const int n = wallar_client_poll_events(c, timeout_ms, events, 64);
    if (n < 0) break;
    int planes_changed = 0, closed = 0;
    for (int i = 0; i < n; ++i) {
      const wallar_event* e = &events[i];
      switch (e->type) {
        case WALLAR_EVENT_PLANE_ADDED:
          printf("event plane-added id=%u model=%llu\n", e->plane_id,
                 (unsigned long long)e->model_version);
          planes_changed = 1;
          break;
        case WALLAR_EVENT_PLANE_UPDATED:
          printf("event plane-updated id=%u model=%llu\n", e->plane_id,
                 (unsigned long long)e->model_version);
          planes_changed = 1;
          break;
        case WALLAR_EVENT_PLANE_REMOVED:
          printf("event plane-removed id=%u subsumed-by=%u\n", e->plane_id, e->subsumed_by);
          planes_changed = 1;
          break;
        case WALLAR_EVENT_TRACKING_CHANGED:
          printf("event tracking=%d t_ns=%lld\n", e->tracking, (long long)e->t_ns);
          break;
        case WALLAR_EVENT_DISCONNECTED:
          printf("event disconnected\n");
          closed = 1;
          break;
      }
    }
    if (planes_changed) print_snapshot(c, "snapshot");
    if (closed) break;
  }
  print_snapshot(c, "final");
  wallar_client_disconnect(c);
  return 0;
}
