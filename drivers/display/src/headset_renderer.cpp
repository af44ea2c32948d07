// SPDX-License-Identifier: Apache-2.0
/// @file headset_renderer.cpp
/// @brief The headset view in OpenGL ES 3: camera background (undistorted in the fragment
/// shader), wall quads and outlines, floor grid, HUD text (OpenCV's Hershey font into a texture)
/// and the optional lens pre-distortion pass.
///
/// Threading: see headset_renderer.hpp.
#include "wallar/drivers/display/headset_renderer.hpp"

#include <GLES3/gl3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "wallar/core/convex_hull.hpp"

namespace wallar::display {
namespace {

// ---- shaders ------------------------------------------------------------------------------

constexpr const char* kQuadVertex = R"(#version 300 es
// A full-viewport quad from gl_VertexID (triangle strip of 4).
out vec2 v_unit;  // (0,0) top-left, (1,1) bottom-right of the viewport
void main() {
  vec2 p = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1));
  v_unit = vec2(p.x, 1.0 - p.y);
  gl_Position = vec4(2.0 * p - 1.0, 0.0, 1.0);
}
)";

// Camera image: the eye's viewport shows the ideal pinhole image of the same K; each pixel
// looks up where the lens put it (radial-tangential model), like cv::initUndistortRectifyMap.
constexpr const char* kCameraFragment = R"(#version 300 es
precision highp float;
uniform sampler2D u_image;
uniform vec2 u_image_size;  // [px]
uniform vec4 u_K;           // fx fy cx cy
uniform vec4 u_radtan;      // k1 k2 p1 p2
uniform int u_undistort;
uniform vec3 u_tint;        // (1, 1, 1); dark red for a frozen image
in vec2 v_unit;
out vec4 frag;
void main() {
  // Pixel-centre coordinates of the ideal image (integer at centres).
  vec2 uv = v_unit * u_image_size - 0.5;
  if (u_undistort == 1) {
    vec2 xy = (uv - u_K.zw) / u_K.xy;
    float r2 = dot(xy, xy);
    float radial = 1.0 + u_radtan.x * r2 + u_radtan.y * r2 * r2;
    vec2 d = xy * radial +
             vec2(2.0 * u_radtan.z * xy.x * xy.y + u_radtan.w * (r2 + 2.0 * xy.x * xy.x),
                  u_radtan.z * (r2 + 2.0 * xy.y * xy.y) + 2.0 * u_radtan.w * xy.x * xy.y);
    uv = d * u_K.xy + u_K.zw;
  }
  vec2 tc = (uv + 0.5) / u_image_size;
  if (any(lessThan(tc, vec2(0.0))) || any(greaterThan(tc, vec2(1.0)))) {
    frag = vec4(0.0, 0.0, 0.0, 1.0);
    return;
  }
  float g = texture(u_image, tc).r;
  frag = vec4(g * u_tint, 1.0);
}
)";

constexpr const char* kWorldVertex = R"(#version 300 es
layout(location = 0) in vec3 a_p_world;
uniform mat4 u_clip_from_world;
void main() { gl_Position = u_clip_from_world * vec4(a_p_world, 1.0); }
)";

constexpr const char* kColourFragment = R"(#version 300 es
precision mediump float;
uniform vec4 u_colour;
out vec4 frag;
void main() { frag = u_colour; }
)";

constexpr const char* kTextureFragment = R"(#version 300 es
precision mediump float;
uniform sampler2D u_texture;
uniform vec2 u_tex_scale;  // the part of the texture shown (the HUD's lines in use)
in vec2 v_unit;
out vec4 frag;
void main() { frag = texture(u_texture, v_unit * u_tex_scale); }
)";

// Lens pre-distortion: the eye's undistorted view (a texture of the whole display) sampled at
// r (1 + k1 r^2 + k2 r^4), r in half-heights from the eye's centre.
constexpr const char* kLensFragment = R"(#version 300 es
precision highp float;
uniform sampler2D u_scene;
uniform vec2 u_scene_size;    // display [px]
uniform vec4 u_eye;           // x, y (GL, bottom-left), w, h of the eye's half [px]
uniform vec2 u_k;
in vec2 v_unit;
out vec4 frag;
void main() {
  vec2 centre = u_eye.xy + 0.5 * u_eye.zw;
  vec2 p = gl_FragCoord.xy - centre;
  float half_h = 0.5 * u_eye.w;
  float r2 = dot(p, p) / (half_h * half_h);
  vec2 src = centre + p * (1.0 + u_k.x * r2 + u_k.y * r2 * r2);
  if (any(lessThan(src, u_eye.xy)) || any(greaterThan(src, u_eye.xy + u_eye.zw))) {
    frag = vec4(0.0, 0.0, 0.0, 1.0);
    return;
  }
  frag = texture(u_scene, src / u_scene_size);
}
)";

/// A shader or program info log as one line of a DisplayError.
[[noreturn]] void throw_gl_log(const std::string& what, char* log, std::size_t size) {
  for (std::size_t i = 0; i < size && log[i] != '\0'; ++i) log[i] = log[i] == '\n' ? ' ' : log[i];
  throw DisplayError("display: " + what + ": " + log);
}

/// A pending GL error after `what` as a DisplayError ("display: WHAT failed (GL error 0x...)").
void throw_if_gl_error(const char* what) {
  if (const GLenum e = glGetError(); e != GL_NO_ERROR) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "display: %s failed (GL error 0x%04x)", what, e);
    throw DisplayError(buf);
  }
}

GLuint compile(GLenum type, const char* source, const char* name) {
  const GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    char log[512] = {};
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    glDeleteShader(shader);
    throw_gl_log(std::string("shader ") + name + " does not compile", log, sizeof log);
  }
  return shader;
}

GLuint link(const char* vertex, const char* fragment, const char* name) {
  const GLuint vs = compile(GL_VERTEX_SHADER, vertex, name);
  const GLuint fs = compile(GL_FRAGMENT_SHADER, fragment, name);
  const GLuint program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    char log[512] = {};
    glGetProgramInfoLog(program, sizeof log, nullptr, log);
    glDeleteProgram(program);
    throw_gl_log(std::string("program ") + name + " does not link", log, sizeof log);
  }
  return program;
}

// ---- geometry -----------------------------------------------------------------------------

/// Clip space from the camera frame for an image of w x h pixels (see the file comment of
/// headset_renderer.hpp for the pixel-centre convention); GL's depth from near..far.
Eigen::Matrix4d clip_from_camera(const EyeCamera& c, double near_m, double far_m) {
  const double w = c.width_px, h = c.height_px;
  Eigen::Matrix4d P = Eigen::Matrix4d::Zero();
  P(0, 0) = 2.0 * c.fx / w;
  P(0, 2) = 2.0 * (c.cx + 0.5) / w - 1.0;
  P(1, 1) = -2.0 * c.fy / h;
  P(1, 2) = 1.0 - 2.0 * (c.cy + 0.5) / h;
  P(2, 2) = (far_m + near_m) / (far_m - near_m);
  P(2, 3) = -2.0 * far_m * near_m / (far_m - near_m);
  P(3, 2) = 1.0;
  return P;
}

double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

/// Clips segment a-b to a convex counter-clockwise polygon (Cyrus-Beck); false if outside.
bool clip_to_convex(const std::vector<Eigen::Vector2d>& poly, Eigen::Vector2d& a,
                    Eigen::Vector2d& b) {
  double t0 = 0.0, t1 = 1.0;
  const Eigen::Vector2d d = b - a;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d& p = poly[i];
    const Eigen::Vector2d edge = poly[(i + 1) % poly.size()] - p;
    // Inside is left of each edge: cross(edge, x - p) >= 0.
    const double num = cross2(edge, a - p);
    const double den = cross2(edge, d);
    if (std::abs(den) < 1e-15) {
      if (num < 0.0) return false;
      continue;
    }
    const double t = -num / den;
    if (den > 0.0) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
    if (t0 > t1) return false;
  }
  const Eigen::Vector2d a0 = a;
  a = a0 + t0 * d;
  b = a0 + t1 * d;
  return true;
}

struct Batch {
  GLenum mode = GL_TRIANGLES;
  GLint first = 0;
  GLsizei count = 0;
  std::array<float, 4> rgba{};
  float line_width = 1.0f;
};

constexpr std::size_t kMaxVertices = 1 << 16;
constexpr int kHudWidthPx = 560;
constexpr int kHudHeightPx = 84;      // two lines
constexpr int kHudLineHeightPx = 46;  // the first line alone

}  // namespace

EyeViewport eye_viewport(int display_width_px, int display_height_px, int eye, int image_width_px,
                         int image_height_px) {
  const int half = display_width_px / 2;
  EyeViewport vp;
  if (image_width_px <= 0 || image_height_px <= 0) {
    vp = {eye * half, 0, half, display_height_px};
    return vp;
  }
  const double scale = std::min(static_cast<double>(half) / image_width_px,
                                static_cast<double>(display_height_px) / image_height_px);
  vp.width = static_cast<int>(std::lround(image_width_px * scale));
  vp.height = static_cast<int>(std::lround(image_height_px * scale));
  vp.x = eye * half + (half - vp.width) / 2;
  vp.y = (display_height_px - vp.height) / 2;
  return vp;
}

struct HeadsetRenderer::Impl {
  DisplayOutput& output;
  RendererOptions options;
  GLuint camera_program = 0, world_program = 0, texture_program = 0, lens_program = 0;
  GLuint vao = 0, vbo = 0;
  std::array<GLuint, 2> image_tex{};
  std::array<int, 2> image_w{}, image_h{};
  GLuint hud_tex = 0;
  GLuint scene_fbo = 0, scene_tex = 0;
  std::vector<float> vertices;  // x y z, capacity kMaxVertices
  std::vector<Batch> batches;
  std::vector<std::pair<double, std::size_t>> order;  // walls far to near
  std::vector<Eigen::Vector2d> hull, scratch;
  cv::Mat hud;  // RGBA
  std::string hud_line;
  float line_width_max = 1.0f;

  Impl(DisplayOutput& out, const RendererOptions& opts, const std::array<EyeCamera, 2>& cameras)
      : output(out), options(opts) {
    camera_program = link(kQuadVertex, kCameraFragment, "camera");
    world_program = link(kWorldVertex, kColourFragment, "world");
    texture_program = link(kQuadVertex, kTextureFragment, "hud");
    lens_program = link(kQuadVertex, kLensFragment, "lens");
    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glGenBuffers(1, &vbo);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(kMaxVertices * 3 * sizeof(float)),
                 nullptr, GL_STREAM_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    glGenTextures(2, image_tex.data());
    glGenTextures(1, &hud_tex);
    for (GLuint t : {image_tex[0], image_tex[1], hud_tex}) {
      glBindTexture(GL_TEXTURE_2D, t);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    }
    hud.create(kHudHeightPx, kHudWidthPx, CV_8UC4);
    glBindTexture(GL_TEXTURE_2D, hud_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, kHudWidthPx, kHudHeightPx, 0, GL_RGBA,
                 GL_UNSIGNED_BYTE, nullptr);
    if (options.lens_k1 != 0.0 || options.lens_k2 != 0.0) {
      glGenTextures(1, &scene_tex);
      glBindTexture(GL_TEXTURE_2D, scene_tex);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, output.width_px(), output.height_px(), 0, GL_RGBA,
                   GL_UNSIGNED_BYTE, nullptr);
      glGenFramebuffers(1, &scene_fbo);
      glBindFramebuffer(GL_FRAMEBUFFER, scene_fbo);
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, scene_tex, 0);
      if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        throw DisplayError("display: the lens pass's off-screen framebuffer is incomplete");
      }
      glBindFramebuffer(GL_FRAMEBUFFER, 0);
    }
    GLfloat range[2] = {1.0f, 1.0f};
    glGetFloatv(GL_ALIASED_LINE_WIDTH_RANGE, range);
    line_width_max = range[1];
    vertices.reserve(kMaxVertices * 3);
    batches.reserve(512);
    order.reserve(64);
    hull.reserve(256);
    scratch.reserve(256);
    hud_line.reserve(160);
    throw_if_gl_error("renderer set-up");
    warm_up(cameras);
  }

  /// Draws one frame with every program and every state a real frame uses (camera images, a
  /// floor's fill, outline and grid, the HUD's two lines, the lens pass), not presented, and
  /// waits for it. A software rasteriser (llvmpipe) compiles a shader's machine code at its
  /// first draw, not at link: seconds under emulation, which the first wall would otherwise
  /// spend inside a draw the supervisor watches (a render thread "stalled" and restarted), and
  /// hundreds of milliseconds natively (the first frames' deadline misses). Images of the
  /// cameras' sizes allocate their textures here, once (a camera of width 0: a small stand-in).
  void warm_up(const std::array<EyeCamera, 2>& cameras) {
    HeadsetFrame frame;
    for (std::size_t i = 0; i < 2; ++i) {
      EyeInput& eye = frame.eyes[i];
      eye.camera = cameras[i];
      if (eye.camera.width_px <= 0 || eye.camera.height_px <= 0) {
        eye.camera = EyeCamera{16, 12, 10.0, 10.0, 8.0, 6.0, {0.01, 0.0, 0.0, 0.0}};
      }
      const int w = eye.camera.width_px, h = eye.camera.height_px;
      eye.image = Image::allocate(w, h, PixelFormat::kGray8);
      std::memset(eye.image.mutable_data(), 128, static_cast<std::size_t>(w) * h);
    }
    WallModel model;
    Wall floor;  // 2 m ahead of both eyes, facing them
    floor.id = 1;
    floor.kind = SurfaceKind::kFloor;
    floor.plane = Plane{-Eigen::Vector3d::UnitZ(), -2.0};
    floor.origin = Eigen::Vector3d(0.0, 0.0, 2.0);
    floor.u = Eigen::Vector3d::UnitX();
    floor.v = -Eigen::Vector3d::UnitY();
    floor.extent_uv_m = {{-1.0, -1.0}, {1.0, -1.0}, {1.0, 1.0}, {-1.0, 1.0}};
    model.walls.push_back(std::move(floor));
    frame.walls = &model;
    frame.hud.degraded = "warm-up";
    compose(frame);
    glFinish();
    throw_if_gl_error("the renderer's warm-up draw");
  }

  ~Impl() {
    glDeleteProgram(camera_program);
    glDeleteProgram(world_program);
    glDeleteProgram(texture_program);
    glDeleteProgram(lens_program);
    glDeleteBuffers(1, &vbo);
    glDeleteVertexArrays(1, &vao);
    glDeleteTextures(2, image_tex.data());
    glDeleteTextures(1, &hud_tex);
    if (scene_fbo != 0) glDeleteFramebuffers(1, &scene_fbo);
    if (scene_tex != 0) glDeleteTextures(1, &scene_tex);
  }

  // -- per frame ----------------------------------------------------------------------------

  bool push(const Eigen::Vector3d& p) {
    if (vertices.size() + 3 > kMaxVertices * 3) return false;
    vertices.push_back(static_cast<float>(p.x()));
    vertices.push_back(static_cast<float>(p.y()));
    vertices.push_back(static_cast<float>(p.z()));
    return true;
  }

  void add_batch(GLenum mode, std::size_t first_vertex, std::array<float, 4> rgba, float width) {
    const auto count = static_cast<GLsizei>(vertices.size() / 3 - first_vertex);
    if (count <= 0 || batches.size() == batches.capacity()) return;
    batches.push_back({mode, static_cast<GLint>(first_vertex), count, rgba, width});
  }

  /// Builds the world geometry of the model (shared by both eyes; culling per eye in draw).
  void build_geometry(const WallModel& model, const Eigen::Vector3d& viewer_world) {
    vertices.clear();
    batches.clear();
    order.clear();
    // At most order.capacity() (64) surfaces are drawn: a room model has a handful.
    for (std::size_t i = 0; i < model.walls.size() && order.size() < order.capacity(); ++i) {
      const Wall& w = model.walls[i];
      if (w.extent_uv_m.size() < 3) continue;
      // Front side only: the viewer must be on the side the normal points to.
      if (w.plane.signed_distance(viewer_world) <= 0.0) continue;
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (std::size_t k = 0; k < w.extent_uv_m.size(); ++k) centre += w.corner(k);
      centre /= static_cast<double>(w.extent_uv_m.size());
      order.emplace_back(-(centre - viewer_world).squaredNorm(), i);
    }
    std::sort(order.begin(), order.end());  // far first: translucent fills blend back to front
    for (const auto& [key, index] : order) {
      const Wall& w = model.walls[index];
      const auto rgb = surface_colour_rgb(w.id);
      const std::array<float, 4> fill{rgb[0] / 255.0f, rgb[1] / 255.0f, rgb[2] / 255.0f,
                                      options.wall_alpha};
      const std::array<float, 4> line{fill[0], fill[1], fill[2], 1.0f};
      scratch.assign(w.extent_uv_m.begin(), w.extent_uv_m.end());
      convex_hull(scratch, hull);
      if (hull.size() < 3) continue;
      auto corner = [&](const Eigen::Vector2d& uv) {
        return w.origin + uv.x() * w.u + uv.y() * w.v;
      };
      std::size_t first = vertices.size() / 3;
      for (const Eigen::Vector2d& uv : hull) push(corner(uv));
      add_batch(GL_TRIANGLE_FAN, first, fill, 1.0f);
      if (options.outlines) {
        first = vertices.size() / 3;
        for (const Eigen::Vector2d& uv : hull) push(corner(uv));
        add_batch(GL_LINE_LOOP, first, line, 3.0f);
      }
      if (options.floor_grid && w.kind == SurfaceKind::kFloor && options.grid_spacing_m > 0.0) {
        Eigen::Vector2d lo = hull[0], hi = hull[0];
        for (const Eigen::Vector2d& uv : hull) {
          lo = lo.cwiseMin(uv);
          hi = hi.cwiseMax(uv);
        }
        first = vertices.size() / 3;
        const double s = options.grid_spacing_m;
        for (int axis = 0; axis < 2; ++axis) {
          for (double t = std::ceil(lo[axis] / s) * s; t <= hi[axis]; t += s) {
            Eigen::Vector2d a = lo, b = hi;
            a[axis] = b[axis] = t;
            if (clip_to_convex(hull, a, b) && !(push(corner(a)) && push(corner(b)))) break;
          }
        }
        add_batch(GL_LINES, first, {1.0f, 1.0f, 1.0f, 0.8f}, 1.5f);
      }
    }
  }

  void upload_image(int eye, const Image& image) {
    if (image.empty() || image.format() != PixelFormat::kGray8) return;
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, image_tex[eye]);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, image.stride_bytes());  // straight from the buffer
    if (image.width() != image_w[eye] || image.height() != image_h[eye]) {
      image_w[eye] = image.width();
      image_h[eye] = image.height();
      glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, image.width(), image.height(), 0, GL_RED,
                   GL_UNSIGNED_BYTE, image.data());
    } else {
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, image.width(), image.height(), GL_RED,
                      GL_UNSIGNED_BYTE, image.data());
    }
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  }

  void set_viewport(const EyeViewport& vp) {
    glViewport(vp.x, output.height_px() - vp.y - vp.height, vp.width, vp.height);
  }

  // Walls are drawn over a live image with a valid pose only.
  static bool overlay(const HeadsetFrame& frame) {
    return frame.pose_valid && !frame.hud.image_frozen;
  }

  void draw_eye(int eye, const HeadsetFrame& frame) {
    const EyeInput& in = frame.eyes[static_cast<std::size_t>(eye)];
    const EyeCamera& cam = in.camera;
    const EyeViewport vp =
        eye_viewport(output.width_px(), output.height_px(), eye, cam.width_px, cam.height_px);
    set_viewport(vp);
    glDisable(GL_BLEND);
    if (!in.image.empty() && in.image.format() == PixelFormat::kGray8 && cam.width_px > 0) {
      glUseProgram(camera_program);
      glActiveTexture(GL_TEXTURE0);
      glBindTexture(GL_TEXTURE_2D, image_tex[eye]);
      glUniform1i(glGetUniformLocation(camera_program, "u_image"), 0);
      glUniform2f(glGetUniformLocation(camera_program, "u_image_size"),
                  static_cast<float>(cam.width_px), static_cast<float>(cam.height_px));
      glUniform4f(glGetUniformLocation(camera_program, "u_K"), static_cast<float>(cam.fx),
                  static_cast<float>(cam.fy), static_cast<float>(cam.cx),
                  static_cast<float>(cam.cy));
      glUniform4f(glGetUniformLocation(camera_program, "u_radtan"),
                  static_cast<float>(cam.radtan[0]), static_cast<float>(cam.radtan[1]),
                  static_cast<float>(cam.radtan[2]), static_cast<float>(cam.radtan[3]));
      glUniform1i(glGetUniformLocation(camera_program, "u_undistort"), options.undistort ? 1 : 0);
      // A frozen image (camera lost) at a third of its light, red: unmistakably not the world.
      if (frame.hud.image_frozen) {
        glUniform3f(glGetUniformLocation(camera_program, "u_tint"), 0.40f, 0.08f, 0.08f);
      } else {
        glUniform3f(glGetUniformLocation(camera_program, "u_tint"), 1.0f, 1.0f, 1.0f);
      }
      glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    }
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    if (overlay(frame) && !batches.empty() && cam.width_px > 0) {
      const Eigen::Matrix4d clip_from_world =
          clip_from_camera(cam, options.near_m, options.far_m) * in.T_world_cam.inverse().matrix();
      const Eigen::Matrix4f m = clip_from_world.cast<float>();
      glUseProgram(world_program);
      glUniformMatrix4fv(glGetUniformLocation(world_program, "u_clip_from_world"), 1, GL_FALSE,
                         m.data());  // Eigen is column-major, as GL expects
      const GLint colour = glGetUniformLocation(world_program, "u_colour");
      glBindVertexArray(vao);
      for (const Batch& b : batches) {
        glUniform4f(colour, b.rgba[0], b.rgba[1], b.rgba[2], b.rgba[3]);
        if (b.mode != GL_TRIANGLE_FAN) {
          glLineWidth(std::min(b.line_width * static_cast<float>(vp.height) / 720.0f + 0.5f,
                               line_width_max));
        }
        glDrawArrays(b.mode, b.first, b.count);
      }
    }
    if (options.hud) {
      // Top-left of the eye, half its width at most; the second line only when degraded.
      const double scale = std::min(1.0, 0.5 * vp.width / static_cast<double>(kHudWidthPx));
      const int rows = frame.hud.degraded.empty() ? kHudLineHeightPx : kHudHeightPx;
      EyeViewport hud_vp{vp.x + vp.width / 40, vp.y + vp.height / 40,
                         static_cast<int>(kHudWidthPx * scale), static_cast<int>(rows * scale)};
      set_viewport(hud_vp);
      glUseProgram(texture_program);
      glActiveTexture(GL_TEXTURE0);
      glBindTexture(GL_TEXTURE_2D, hud_tex);
      glUniform1i(glGetUniformLocation(texture_program, "u_texture"), 0);
      glUniform2f(glGetUniformLocation(texture_program, "u_tex_scale"), 1.0f,
                  static_cast<float>(rows) / static_cast<float>(kHudHeightPx));
      glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    }
  }

  void update_hud(const HeadsetFrame& frame) {
    hud.setTo(cv::Scalar(0, 0, 0, 140));
    const HudState& h = frame.hud;
    char line[128];
    if (h.image_frozen) {
      std::snprintf(line, sizeof line, "CAMERA LOST: image frozen");
    } else {
      std::snprintf(line, sizeof line, "%s  %.1f fps  %d wall%s",
                    frame.pose_valid ? h.tracking.c_str() : "LOST", h.fps, h.walls,
                    h.walls == 1 ? "" : "s");
    }
    hud_line.assign(line);
    cv::putText(hud, hud_line, cv::Point(12, 32), cv::FONT_HERSHEY_SIMPLEX, 0.8,
                h.image_frozen ? cv::Scalar(255, 60, 60, 255) : cv::Scalar(255, 255, 255, 255), 2,
                cv::LINE_AA);
    if (!h.degraded.empty()) {
      std::snprintf(line, sizeof line, "DEGRADED: %s", h.degraded.c_str());
      hud_line.assign(line);
      cv::putText(hud, hud_line, cv::Point(12, 70), cv::FONT_HERSHEY_SIMPLEX, 0.7,
                  cv::Scalar(255, 160, 0, 255), 2, cv::LINE_AA);
    }
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, hud_tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    // Row 0 of the Mat is the HUD's top; the quad samples t = 0 at its top.
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, kHudWidthPx, kHudHeightPx, GL_RGBA, GL_UNSIGNED_BYTE,
                    hud.data);
  }

  void lens_pass() {
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, output.width_px(), output.height_px());
    glDisable(GL_BLEND);
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    glUseProgram(lens_program);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, scene_tex);
    glUniform1i(glGetUniformLocation(lens_program, "u_scene"), 0);
    glUniform2f(glGetUniformLocation(lens_program, "u_scene_size"),
                static_cast<float>(output.width_px()), static_cast<float>(output.height_px()));
    glUniform2f(glGetUniformLocation(lens_program, "u_k"), static_cast<float>(options.lens_k1),
                static_cast<float>(options.lens_k2));
    const int half = output.width_px() / 2;
    for (int eye = 0; eye < 2; ++eye) {
      glViewport(eye * half, 0, half, output.height_px());
      glUniform4f(glGetUniformLocation(lens_program, "u_eye"), static_cast<float>(eye * half), 0.0f,
                  static_cast<float>(half), static_cast<float>(output.height_px()));
      glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    }
  }

  /// Both eyes (and the lens pass) into the default framebuffer, not presented.
  void compose(const HeadsetFrame& frame) {
    glBindFramebuffer(GL_FRAMEBUFFER, scene_fbo);  // 0 without the lens pass
    glViewport(0, 0, output.width_px(), output.height_px());
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    for (int eye = 0; eye < 2; ++eye) upload_image(eye, frame.eyes[eye].image);
    if (frame.walls != nullptr && overlay(frame)) {
      // Culled for the midpoint of the eyes: a wall seen edge-on is invisible to both.
      const Eigen::Vector3d viewer =
          0.5 * (frame.eyes[0].T_world_cam.translation() + frame.eyes[1].T_world_cam.translation());
      build_geometry(*frame.walls, viewer);
      glBindBuffer(GL_ARRAY_BUFFER, vbo);
      glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(vertices.size() * sizeof(float)),
                      vertices.data());
    } else {
      vertices.clear();
      batches.clear();
    }
    if (options.hud) update_hud(frame);
    for (int eye = 0; eye < 2; ++eye) draw_eye(eye, frame);
    if (scene_fbo != 0) lens_pass();
  }

  RenderTiming draw(const HeadsetFrame& frame, std::span<std::uint8_t> capture_rgba) {
    const TimeNs t0 = monotonic_now_ns();
    RenderTiming timing;
    compose(frame);
    if (!capture_rgba.empty()) output.read_pixels(capture_rgba);  // the default framebuffer
    timing.presented = output.present(timing.present_t_ns);
    timing.render_ns = timing.present_t_ns - t0;
    if (frame.capture_t_ns > 0) timing.latency_ns = timing.present_t_ns - frame.capture_t_ns;
    return timing;
  }
};

HeadsetRenderer::HeadsetRenderer(DisplayOutput& output, const RendererOptions& options,
                                 const std::array<EyeCamera, 2>& cameras)
    : impl_(std::make_unique<Impl>(output, options, cameras)) {}
HeadsetRenderer::~HeadsetRenderer() = default;
RenderTiming HeadsetRenderer::draw(const HeadsetFrame& frame,
                                   std::span<std::uint8_t> capture_rgba) {
  return impl_->draw(frame, capture_rgba);
}
const RendererOptions& HeadsetRenderer::options() const { return impl_->options; }

}  // namespace wallar::display
