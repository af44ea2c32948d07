/* SPDX-License-Identifier: Apache-2.0 */
/**
 * @file draw_planes.c
 * @brief A small libwallar-client app with OpenGL ES 2 through EGL: at its own display rate it
 * asks for the head pose predicted to its display time (now + --ahead-ms), puts the eye there
 * (the located body pose times wallar_client_view(), T_body_view: the rectified left camera)
 * and draws every plane's polygon filled, coloured by its label. Headless (Mesa's surfaceless
 * EGL platform and a pbuffer; llvmpipe renders it without a GPU); --out writes the last frame.
 *
 *   draw_planes --socket /run/wallar/client.sock [--rate 60] [--ahead-ms 16] [--size 640x480]
 *               [--fov-deg 80] [--out last.ppm] [--wait 10] [--duration S]
 *
 * Output lines: "view q_body_view=x,y,z,w p_body_view=x,y,z"; whenever the set changes
 * "planes model=V count=N" and N lines "plane id=... label=... world=x,y,z;..." (the polygon
 * in the world); per display frame "frame n=... t_ns=... past_pose_ms=... draw_ms=... planes=N
 * p_world_body=... q_world_body=... p_world_view=x,y,z q_world_view=x,y,z,w" (past_pose_ms: how
 * far past the newest tracked pose the pose was predicted), or "frame n=... no pose
 * tracking=T" before the first pose; at the end "summary frames=... drawn=... missed=..."
 * (missed: refreshes skipped for being late) with the mean prediction and draw times.
 * The camera model is a pinhole of --fov-deg (horizontal) centred on the image, x right, y
 * down, z forward (the view's axes); the client API does not carry the camera's intrinsics.
 *
 * Colours (RGB): floor 40,200,60; wall 40,90,230; ceiling 230,200,40; unknown 150,150,150;
 * nothing 0,0,0. Exit: 0 at --duration, 1 when the firmware goes away (one line on stderr; the
 * summary and --out still come), 2 for bad options.
 *
 * Threading: one thread (the C API's contract, and EGL's current context).
 */
#define _POSIX_C_SOURCE 200809L /* clock_gettime, nanosleep under -std=c11 (example_common.h) */

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES2/gl2.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "example_common.h"
#include "wallar_client.h"

#define MAX_PLANES 256

/* A plane ready to draw: its polygon in the world (x, y, z per vertex) and its label. */
typedef struct {
  uint32_t id;
  int32_t label;
  uint32_t vertex_count;
  float* xyz_world_m;
} drawn_plane;

static void label_rgb(int32_t l, float rgb[3]) {
  static const float kRgb[4][3] = {{150, 150, 150}, {40, 200, 60}, {40, 90, 230}, {230, 200, 40}};
  const int i = l >= 0 && l <= 3 ? l : 0;
  for (int k = 0; k < 3; ++k) rgb[k] = kRgb[i][k] / 255.0f;
}

/* q_ab * q_bc (x, y, z, w). */
static void compose(const double a[4], const double b[4], double out[4]) {
  out[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
  out[1] = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
  out[2] = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
  out[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
}

/*
 * The column-major matrix from the world to GL's clip space for an eye at (q, p) = T_world_view
 * (x right, y down, z forward) with a pinhole of focal length f_px centred in a w x h image:
 * x_clip = 2 f / w x, y_clip = -2 f / h y (GL's y is up), w_clip = z, depth from near to far.
 */
static void clip_from_world(const double q_world_view[4], const double p_world_view_m[3],
                            double f_px, int w_px, int h_px, float m[16]) {
  const double near_m = 0.05, far_m = 100.0;
  const double q_view_world[4] = {-q_world_view[0], -q_world_view[1], -q_world_view[2],
                                  q_world_view[3]};
  double r[3][3], t[3]; /* R_view_world (row i: view axis i in the world) and t_view_world */
  for (int j = 0; j < 3; ++j) {
    const double e[3] = {j == 0, j == 1, j == 2};
    double col[3];
    example_rotate(q_view_world, e, col);
    for (int i = 0; i < 3; ++i) r[i][j] = col[i];
  }
  example_rotate(q_view_world, p_world_view_m, t);
  for (int i = 0; i < 3; ++i) t[i] = -t[i];
  const double sx = 2 * f_px / w_px, sy = -2 * f_px / h_px;
  const double az = (far_m + near_m) / (far_m - near_m),
               bz = -2 * far_m * near_m / (far_m - near_m);
  const double rows[4][4] = {{sx * r[0][0], sx * r[0][1], sx * r[0][2], sx * t[0]},
                             {sy * r[1][0], sy * r[1][1], sy * r[1][2], sy * t[1]},
                             {az * r[2][0], az * r[2][1], az * r[2][2], az * t[2] + bz},
                             {r[2][0], r[2][1], r[2][2], t[2]}};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) m[4 * j + i] = (float)rows[i][j];
}

/* The snapshot's planes into `planes` (world polygons); returns how many. */
static int load_planes(wallar_client* c, drawn_plane* planes, int n_old) {
  for (int i = 0; i < n_old; ++i) free(planes[i].xyz_world_m);
  wallar_planes* snapshot = NULL;
  if (wallar_client_begin_planes(c, &snapshot) != 0) return 0;
  int n = 0;
  printf("planes model=%llu count=%zu\n", (unsigned long long)wallar_planes_model_version(snapshot),
         wallar_planes_count(snapshot));
  for (size_t i = 0; i < wallar_planes_count(snapshot) && n < MAX_PLANES; ++i) {
    wallar_plane p;
    if (wallar_planes_get(snapshot, i, &p) != 0 || p.vertex_count < 3) continue;
    double* xyz_world_m = example_polygon_world(snapshot, i, &p);
    float* xyz = malloc(3 * sizeof(float) * p.vertex_count);
    if (xyz_world_m == NULL || xyz == NULL) {
      free(xyz_world_m);
      free(xyz);
      break;
    }
    for (uint32_t k = 0; k < 3 * p.vertex_count; ++k) xyz[k] = (float)xyz_world_m[k];
    printf("plane id=%u label=%s world=", p.id, example_label_name(p.label));
    example_print_points(xyz_world_m, p.vertex_count);
    printf("\n");
    free(xyz_world_m);
    planes[n++] = (drawn_plane){p.id, p.label, p.vertex_count, xyz};
  }
  wallar_planes_end(snapshot);
  return n;
}

static const char* kVertexShader =
    "uniform mat4 clip_from_world;\n"
    "attribute vec3 p_world;\n"
    "void main() { gl_Position = clip_from_world * vec4(p_world, 1.0); }\n";
static const char* kFragmentShader =
    "precision mediump float;\n"
    "uniform vec3 rgb;\n"
    "void main() { gl_FragColor = vec4(rgb, 1.0); }\n";

static GLuint compile(GLenum type, const char* source) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &source, NULL);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[512] = "";
    glGetShaderInfoLog(s, sizeof log, NULL, log);
    fprintf(stderr, "draw_planes: error: shader: %s\n", log);
    exit(1);
  }
  return s;
}

/* EGL on Mesa's surfaceless platform with a w x h RGBA8 + depth pbuffer, OpenGL ES 2 current. */
static int open_egl(int w_px, int h_px, EGLDisplay* out) {
  const char* ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display =
      (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
  if (ext == NULL || strstr(ext, "EGL_MESA_platform_surfaceless") == NULL ||
      get_platform_display == NULL) {
    fprintf(stderr,
            "draw_planes: error: EGL lacks EGL_MESA_platform_surfaceless (Mesa's libEGL: "
            "apt install libegl-mesa0)\n");
    return -1;
  }
  const EGLDisplay d =
      get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE,
                                   EGL_PBUFFER_BIT,
                                   EGL_RENDERABLE_TYPE,
                                   EGL_OPENGL_ES2_BIT,
                                   EGL_RED_SIZE,
                                   8,
                                   EGL_GREEN_SIZE,
                                   8,
                                   EGL_BLUE_SIZE,
                                   8,
                                   EGL_DEPTH_SIZE,
                                   16,
                                   EGL_NONE};
  const EGLint context_attribs[] = {EGL_CONTEXT_CLIENT_VERSION, 2, EGL_NONE};
  const EGLint surface_attribs[] = {EGL_WIDTH, w_px, EGL_HEIGHT, h_px, EGL_NONE};
  EGLConfig config = NULL;
  EGLint configs = 0;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface surface = EGL_NO_SURFACE;
  const char* step = "eglInitialize (surfaceless)";
  if (d != EGL_NO_DISPLAY && eglInitialize(d, NULL, NULL)) {
    step = "eglChooseConfig (RGBA8 pbuffer, OpenGL ES 2)";
    if (eglBindAPI(EGL_OPENGL_ES_API) && eglChooseConfig(d, config_attribs, &config, 1, &configs) &&
        configs > 0) {
      step = "eglCreateContext (OpenGL ES 2)";
      context = eglCreateContext(d, config, EGL_NO_CONTEXT, context_attribs);
    }
    if (context != EGL_NO_CONTEXT) {
      step = "eglCreatePbufferSurface";
      surface = eglCreatePbufferSurface(d, config, surface_attribs);
    }
    if (surface != EGL_NO_SURFACE) {
      step = "eglMakeCurrent";
      if (eglMakeCurrent(d, surface, surface, context)) {
        *out = d;
        return 0;
      }
    }
  }
  fprintf(stderr, "draw_planes: error: %s failed (EGL error 0x%04x)\n", step,
          (unsigned)eglGetError());
  return -1;
}

/* The w x h frame now in the pbuffer as a binary PPM (rows top first). */
static int write_ppm(const char* path, int w_px, int h_px) {
  unsigned char* rgba = malloc((size_t)w_px * h_px * 4);
  FILE* f = fopen(path, "wb");
  int ok = rgba != NULL && f != NULL;
  if (ok) {
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, w_px, h_px, GL_RGBA, GL_UNSIGNED_BYTE, rgba);
    ok = fprintf(f, "P6\n%d %d\n255\n", w_px, h_px) > 0;
    for (int y = h_px - 1; ok && y >= 0; --y) /* GL's first row is the bottom one */
      for (int x = 0; ok && x < w_px; ++x)
        ok = fwrite(rgba + 4 * ((size_t)y * w_px + x), 3, 1, f) == 1;
  }
  if (f != NULL && fclose(f) != 0) ok = 0;
  free(rgba);
  if (!ok) fprintf(stderr, "draw_planes: error: cannot write %s\n", path);
  return ok ? 0 : -1;
}

int main(int argc, char** argv) {
  example_options o = {"/run/wallar/client.sock", 60.0, 16.0, 10.0, 0.0};
  const char* out_path = NULL;
  double fov_deg = 80.0;
  int w_px = 640, h_px = 480;
  for (int i = 1; i < argc; i += 2) { /* options come in pairs: NAME VALUE */
    const char* a = argv[i];
    const char* v = i + 1 < argc ? argv[i + 1] : NULL;
    if (v != NULL && example_option(&o, a, v)) continue;
    if (v != NULL && strcmp(a, "--out") == 0) {
      out_path = v;
    } else if (v != NULL && strcmp(a, "--fov-deg") == 0) {
      fov_deg = atof(v);
    } else if (v != NULL && strcmp(a, "--size") == 0) {
      if (sscanf(v, "%dx%d", &w_px, &h_px) != 2) w_px = 0; /* refused below */
    } else {
      fprintf(stderr,
              "usage: draw_planes [--socket PATH] [--rate HZ] [--ahead-ms MS] [--size WxH] "
              "[--fov-deg DEG] [--out FILE.ppm] [--wait S] [--duration S]\n");
      return 2;
    }
  }
  const char* socket_path = o.socket_path;
  const double rate_hz = o.rate_hz, ahead_ms = o.ahead_ms, duration_s = o.duration_s;
  if (!(rate_hz > 0.0 && rate_hz <= 1000.0) || !(fov_deg > 1.0 && fov_deg < 179.0) || w_px < 16 ||
      h_px < 16 || w_px > 4096 || h_px > 4096) {
    fprintf(stderr,
            "draw_planes: error: --rate must be in (0, 1000] Hz, --fov-deg in (1, 179), "
            "--size in 16x16..4096x4096\n");
    return 2;
  }
  wallar_client* c = example_connect(socket_path, "draw_planes", o.wait_s);
  if (c == NULL) return 1;
  /* Where to render from: the headset's eye (its rectified left camera) in the body frame. */
  double q_body_view[4], p_body_view_m[3];
  if (wallar_client_view(c, q_body_view, p_body_view_m) != 0) {
    fprintf(stderr, "draw_planes: error: no consistent view from the firmware's shared memory\n");
    wallar_client_disconnect(c);
    return 1;
  }
  EGLDisplay display = EGL_NO_DISPLAY;
  if (open_egl(w_px, h_px, &display) != 0) {
    wallar_client_disconnect(c);
    return 1;
  }
  printf("connected %s, rendering %dx%d on %s\n", socket_path, w_px, h_px,
         (const char*)glGetString(GL_RENDERER));
  printf("view q_body_view=%.6f,%.6f,%.6f,%.6f p_body_view=%.6f,%.6f,%.6f\n", q_body_view[0],
         q_body_view[1], q_body_view[2], q_body_view[3], p_body_view_m[0], p_body_view_m[1],
         p_body_view_m[2]);
  const GLuint program = glCreateProgram();
  glAttachShader(program, compile(GL_VERTEX_SHADER, kVertexShader));
  glAttachShader(program, compile(GL_FRAGMENT_SHADER, kFragmentShader));
  glBindAttribLocation(program, 0, "p_world");
  glLinkProgram(program);
  glUseProgram(program);
  const GLint clip_from_world_loc = glGetUniformLocation(program, "clip_from_world");
  const GLint rgb_loc = glGetUniformLocation(program, "rgb");
  glEnableVertexAttribArray(0);
  glEnable(GL_DEPTH_TEST); /* the nearer plane wins where planes overlap in the view */
  glViewport(0, 0, w_px, h_px);
  const double f_px = 0.5 * w_px / tan(0.5 * fov_deg * 3.14159265358979 / 180.0);

  static drawn_plane planes[MAX_PLANES];
  int n_planes = 0;
  int frames = 0, drawn = 0, missed = 0, exit_code = 0;
  double draw_ms_sum = 0, draw_ms_max = 0, past_pose_ms_sum = 0;
  const int64_t period_ns = (int64_t)(1e9 / rate_hz);
  const int64_t start_ns = example_monotonic_ns();
  const int64_t end_ns = duration_s > 0 ? start_ns + (int64_t)(duration_s * 1e9) : INT64_MAX;
  int64_t next_ns = start_ns;
  for (;;) {
    int64_t now_ns = example_monotonic_ns();
    if (now_ns >= end_ns) {
      /* Refreshes before the end that came while the app was busy elsewhere were skipped. */
      if (next_ns < end_ns) missed += (int)((end_ns - 1 - next_ns) / period_ns + 1);
      break;
    }
    if (now_ns >= next_ns) {
      /* A display frame: the eye's pose at its display time, in the sensors' clock. */
      const int64_t t_display_ns = wallar_client_now_ns(c) + (int64_t)(ahead_ms * 1e6);
      wallar_pose pose;
      const uint32_t valid = WALLAR_POSE_ORIENTATION_VALID | WALLAR_POSE_POSITION_VALID;
      if (wallar_client_locate(c, t_display_ns, &pose) != 0 || (pose.flags & valid) != valid) {
        printf("frame n=%d no pose tracking=%d\n", frames, wallar_client_tracking(c));
      } else {
        const int64_t t0_ns = example_monotonic_ns();
        double q_world_view[4], p_world_view_m[3];
        compose(pose.q_world_body_xyzw, q_body_view, q_world_view);
        example_rotate(pose.q_world_body_xyzw, p_body_view_m, p_world_view_m);
        for (int k = 0; k < 3; ++k) p_world_view_m[k] += pose.p_world_body_m[k];
        float m[16], rgb[3];
        clip_from_world(q_world_view, p_world_view_m, f_px, w_px, h_px, m);
        glClearColor(0, 0, 0, 1);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glUniformMatrix4fv(clip_from_world_loc, 1, GL_FALSE, m);
        for (int i = 0; i < n_planes; ++i) {
          /* The firmware's polygons are convex (each surface's hull), so a fan fills them;
           * a concave polygon would need triangulating or a stencil pass. */
          label_rgb(planes[i].label, rgb);
          glUniform3fv(rgb_loc, 1, rgb);
          glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, planes[i].xyz_world_m);
          glDrawArrays(GL_TRIANGLE_FAN, 0, (GLsizei)planes[i].vertex_count);
        }
        glFinish(); /* a display app would eglSwapBuffers here */
        const double draw_ms = (example_monotonic_ns() - t0_ns) / 1e6;
        const double past_pose_ms = (t_display_ns - pose.t_pose_ns) / 1e6;
        printf(
            "frame n=%d t_ns=%lld past_pose_ms=%.1f draw_ms=%.2f planes=%d "
            "p_world_body=%.6f,%.6f,%.6f q_world_body=%.6f,%.6f,%.6f,%.6f "
            "p_world_view=%.6f,%.6f,%.6f q_world_view=%.6f,%.6f,%.6f,%.6f\n",
            frames, (long long)t_display_ns, past_pose_ms, draw_ms, n_planes,
            pose.p_world_body_m[0], pose.p_world_body_m[1], pose.p_world_body_m[2],
            pose.q_world_body_xyzw[0], pose.q_world_body_xyzw[1], pose.q_world_body_xyzw[2],
            pose.q_world_body_xyzw[3], p_world_view_m[0], p_world_view_m[1], p_world_view_m[2],
            q_world_view[0], q_world_view[1], q_world_view[2], q_world_view[3]);
        ++drawn;
        draw_ms_sum += draw_ms;
        past_pose_ms_sum += past_pose_ms;
        if (draw_ms > draw_ms_max) draw_ms_max = draw_ms;
      }
      ++frames;
      /* A display skips the refreshes it was too late for; those after the run's end (a
       * last frame that took long) are not the run's. */
      next_ns += period_ns;
      now_ns = example_monotonic_ns();
      if (next_ns <= now_ns) {
        const int64_t late = (now_ns - next_ns) / period_ns + 1;
        const int64_t last_ns = (now_ns < end_ns ? now_ns : end_ns - 1);
        if (next_ns <= last_ns) missed += (int)((last_ns - next_ns) / period_ns + 1);
        next_ns += late * period_ns;
      }
    }
    int timeout_ms = (int)((next_ns - example_monotonic_ns()) / 1000000);
    if (timeout_ms < 0) timeout_ms = 0;
    wallar_event events[64];
    const int n = wallar_client_poll_events(c, timeout_ms, events, 64);
    int planes_changed = 0, closed = n < 0;
    for (int i = 0; i < n; ++i) {
      planes_changed |= events[i].type == WALLAR_EVENT_PLANE_ADDED ||
                        events[i].type == WALLAR_EVENT_PLANE_UPDATED ||
                        events[i].type == WALLAR_EVENT_PLANE_REMOVED;
      closed |= events[i].type == WALLAR_EVENT_DISCONNECTED;
    }
    if (planes_changed) n_planes = load_planes(c, planes, n_planes);
    if (closed) {
      fprintf(stderr, "draw_planes: error: the firmware closed the connection after %d frames\n",
              frames);
      exit_code = 1;
      break;
    }
    fflush(stdout);
  }
  if (out_path != NULL && write_ppm(out_path, w_px, h_px) != 0) exit_code = 1;
  const int d = drawn > 0 ? drawn : 1;
  printf(
      "summary frames=%d drawn=%d missed=%d planes=%d rate_hz=%.1f seconds=%.2f "
      "past_pose_ms_mean=%.1f draw_ms_mean=%.2f draw_ms_max=%.2f\n",
      frames, drawn, missed, n_planes, rate_hz, (example_monotonic_ns() - start_ns) / 1e9,
      past_pose_ms_sum / d, draw_ms_sum / d, draw_ms_max);
  for (int i = 0; i < n_planes; ++i) free(planes[i].xyz_world_m);
  /* EGL is left to the process's exit: eglTerminate would unload llvmpipe with allocations of
   * its own still listed, which LeakSanitizer then reports against no module (the firmware's
   * headset view does the same). */
  wallar_client_disconnect(c);
  return exit_code;
}
