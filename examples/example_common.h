/* SPDX-License-Identifier: Apache-2.0 */
/**
 * @file example_common.h
 * @brief What the client API's examples share, header-only (copy it with an example): the
 * monotonic clock, a label's name, a quaternion rotation, a plane's polygon in the world, and
 * a connect that waits for the firmware to start. Define _POSIX_C_SOURCE 200809L before the
 * first include (clock_gettime, nanosleep under -std=c11).
 */
#ifndef WALLAR_EXAMPLE_COMMON_H
#define WALLAR_EXAMPLE_COMMON_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "wallar_client.h"

static inline int64_t example_monotonic_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

static inline const char* example_label_name(int32_t label) {
  switch (label) {
    case WALLAR_LABEL_FLOOR:
      return "floor";
    case WALLAR_LABEL_WALL:
      return "wall";
    case WALLAR_LABEL_CEILING:
      return "ceiling";
    default:
      return "unknown";
  }
}

/* v' = q v q* for a unit quaternion (x, y, z, w). */
static inline void example_rotate(const double q[4], const double v[3], double out[3]) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  const double tx = 2 * (y * v[2] - z * v[1]), ty = 2 * (z * v[0] - x * v[2]),
               tz = 2 * (x * v[1] - y * v[0]);
  out[0] = v[0] + w * tx + (y * tz - z * ty);
  out[1] = v[1] + w * ty + (z * tx - x * tz);
  out[2] = v[2] + w * tz + (x * ty - y * tx);
}

/*
 * Plane `index` of a snapshot (`p` its wallar_planes_get) as its polygon in the world: the
 * plane frame's pose applied to the polygon (x, y, 0 in the plane frame). Returns
 * 3 * p->vertex_count doubles (x, y, z per vertex) to free(), or NULL without memory.
 */
static inline double* example_polygon_world(const wallar_planes* planes, size_t index,
                                            const wallar_plane* p) {
  double* xy = malloc(2 * sizeof(double) * (p->vertex_count + 1));
  double* xyz = malloc(3 * sizeof(double) * (p->vertex_count + 1));
  if (xy != NULL && xyz != NULL) {
    wallar_planes_polygon(planes, index, xy, p->vertex_count);
    for (uint32_t k = 0; k < p->vertex_count; ++k) {
      const double local[3] = {xy[2 * k], xy[2 * k + 1], 0.0};
      example_rotate(p->q_world_plane_xyzw, local, &xyz[3 * k]);
      for (int a = 0; a < 3; ++a) xyz[3 * k + a] += p->p_world_plane_m[a];
    }
  } else {
    free(xyz);
    xyz = NULL;
  }
  free(xy);
  return xyz;
}

/* "x,y,z;x,y,z;..." (metres, 1e-6) for n points. */
static inline void example_print_points(const double* xyz, uint32_t n) {
  for (uint32_t k = 0; k < n; ++k) {
    printf("%s%.6f,%.6f,%.6f", k ? ";" : "", xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]);
  }
}

/* The options both examples take, with their defaults set by the app. */
typedef struct {
  const char* socket_path; /* --socket PATH */
  double rate_hz;          /* --rate HZ: the app's display rate */
  double ahead_ms;         /* --ahead-ms MS: display time = now + this */
  double wait_s;           /* --wait S: for the socket to appear */
  double duration_s;       /* --duration S: 0 until the firmware stops */
} example_options;

/* Takes `name value` into `o` if it is one of example_options' (returns 1), else returns 0. */
static inline int example_option(example_options* o, const char* name, const char* value) {
  if (strcmp(name, "--socket") == 0) {
    o->socket_path = value;
  } else if (strcmp(name, "--rate") == 0) {
    o->rate_hz = atof(value);
  } else if (strcmp(name, "--ahead-ms") == 0) {
    o->ahead_ms = atof(value);
  } else if (strcmp(name, "--wait") == 0) {
    o->wait_s = atof(value);
  } else if (strcmp(name, "--duration") == 0) {
    o->duration_s = atof(value);
  } else {
    return 0;
  }
  return 1;
}

/*
 * Connects as `app`, retrying for `wait_s` while the socket is not there yet (the firmware
 * may still be starting; a refusal is final). NULL after one line "APP: error: ..." on stderr.
 */
static inline wallar_client* example_connect(const char* path, const char* app, double wait_s) {
  wallar_client* c = NULL;
  char error[512] = "";
  const int64_t give_up_ns = example_monotonic_ns() + (int64_t)(wait_s * 1e9);
  while (wallar_client_connect(path, app, &c, error, sizeof error) != 0) {
    if (strstr(error, "refused:") != NULL || example_monotonic_ns() > give_up_ns) {
      fprintf(stderr, "%s: error: %s\n", app, error);
      return NULL;
    }
    struct timespec ts = {0, 50000000};
    nanosleep(&ts, NULL);
  }
  return c;
}

#endif /* WALLAR_EXAMPLE_COMMON_H */
