// SPDX-License-Identifier: Apache-2.0
/// @file egl_headless.cpp
/// @brief The headless display: EGL on Mesa's surfaceless platform with an RGBA8 pbuffer
/// (llvmpipe renders it on the CPU when there is no GPU), and the backend dispatch.
///
/// Threading: see display_output.hpp (all calls on the opening thread).
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl32.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <vector>

#include "egl_handles.hpp"
#include "wallar/drivers/display/display_output.hpp"

namespace wallar::display {
namespace {

std::string egl_error_text(const char* what) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%s failed (EGL error 0x%04x)", what,
                static_cast<unsigned>(eglGetError()));
  return buf;
}

class HeadlessOutput final : public DisplayOutput {
 public:
  explicit HeadlessOutput(const DisplayOptions& options)
      : width_px_(options.width_px), height_px_(options.height_px) {
    if (width_px_ <= 0 || height_px_ <= 0 || width_px_ > 8192 || height_px_ > 8192) {
      throw DisplayError("display: headless: size " + std::to_string(width_px_) + "x" +
                         std::to_string(height_px_) + " is not in 1..8192");
    }
    auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (get_platform_display == nullptr) {
      throw DisplayError(
          "display: headless: EGL has no eglGetPlatformDisplayEXT (Mesa's libEGL "
          "is needed: apt install libegl-mesa0)");
    }
    EGLDisplay display =
        get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    EGLint major = 0, minor = 0;
    if (display == EGL_NO_DISPLAY || eglInitialize(display, &major, &minor) == EGL_FALSE) {
      throw DisplayError(
          "display: headless: " + egl_error_text("EGL surfaceless platform initialisation") +
          " (apt install libegl-mesa0 libgl1-mesa-dri)");
    }
    egl_.display = display;
    // Mesa's surfaceless display is one per process: initialised once, never terminated
    // (terminating unloads llvmpipe, whose allocations LeakSanitizer then cannot attribute).
    egl_.terminate = false;
    fail_unless(eglBindAPI(EGL_OPENGL_ES_API), "eglBindAPI(OpenGL ES)");
    const EGLint config_attribs[] = {EGL_SURFACE_TYPE,
                                     EGL_PBUFFER_BIT,
                                     EGL_RENDERABLE_TYPE,
                                     EGL_OPENGL_ES3_BIT,
                                     EGL_RED_SIZE,
                                     8,
                                     EGL_GREEN_SIZE,
                                     8,
                                     EGL_BLUE_SIZE,
                                     8,
                                     EGL_ALPHA_SIZE,
                                     8,
                                     EGL_DEPTH_SIZE,
                                     16,
                                     EGL_NONE};
    EGLConfig config = nullptr;
    EGLint configs = 0;
    fail_unless(eglChooseConfig(display, config_attribs, &config, 1, &configs) && configs > 0,
                "eglChooseConfig(RGBA8 pbuffer, OpenGL ES 3)");
    const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_NONE};
    egl_.context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attribs);
    fail_unless(egl_.context != EGL_NO_CONTEXT, "eglCreateContext(OpenGL ES 3)");
    const EGLint surface_attribs[] = {EGL_WIDTH, width_px_, EGL_HEIGHT, height_px_, EGL_NONE};
    egl_.surface = eglCreatePbufferSurface(display, config, surface_attribs);
    fail_unless(egl_.surface != EGL_NO_SURFACE, "eglCreatePbufferSurface");
    fail_unless(eglMakeCurrent(display, egl_.surface, egl_.surface, egl_.context),
                "eglMakeCurrent");
    const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    renderer_ = renderer != nullptr ? renderer : "unknown renderer";
  }

  [[nodiscard]] int width_px() const override { return width_px_; }
  [[nodiscard]] int height_px() const override { return height_px_; }
  [[nodiscard]] std::string describe() const override {
    return "headless " + std::to_string(width_px_) + "x" + std::to_string(height_px_) + " (" +
           renderer_ + ")";
  }

  [[nodiscard]] bool present(TimeNs& t_ns) override {
    glFinish();
    const GLenum status = glGetGraphicsResetStatus();
    t_ns = monotonic_now_ns();
    if (status != GL_NO_ERROR) {
      last_error_ = "headless: the GL context was reset";
      return false;
    }
    return true;
  }

  void read_pixels(std::span<std::uint8_t> rgba) override {
    const std::size_t row = static_cast<std::size_t>(width_px_) * 4;
    if (rgba.size() < row * static_cast<std::size_t>(height_px_)) {
      throw DisplayError("display: read_pixels: buffer of " + std::to_string(rgba.size()) +
                         " bytes is smaller than the " + std::to_string(width_px_) + "x" +
                         std::to_string(height_px_) + " RGBA frame");
    }
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width_px_, height_px_, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    // GL's first row is the bottom one.
    for (int y = 0; y < height_px_ / 2; ++y) {
      std::swap_ranges(rgba.begin() + static_cast<std::ptrdiff_t>(row * y),
                       rgba.begin() + static_cast<std::ptrdiff_t>(row * (y + 1)),
                       rgba.begin() + static_cast<std::ptrdiff_t>(row * (height_px_ - 1 - y)));
    }
  }

  [[nodiscard]] const std::string& last_error() const override { return last_error_; }

 private:
  static void fail_unless(bool ok, const char* what) {
    if (!ok) throw DisplayError("display: headless: " + egl_error_text(what));
  }

  int width_px_;
  int height_px_;
  detail::EglHandles egl_;
  std::string renderer_;
  std::string last_error_;
};

}  // namespace

DisplayBackend parse_display_backend(const std::string& name) {
  if (name == "headless") return DisplayBackend::kHeadless;
  if (name == "kms") return DisplayBackend::kKms;
  throw DisplayError("display: unknown backend '" + name + "' (known: headless, kms)");
}

Image rgba_to_rgb(std::span<const std::uint8_t> rgba, int width_px, int height_px) {
  Image rgb = Image::allocate(width_px, height_px, PixelFormat::kRgb8);
  for (int y = 0; y < height_px; ++y) {
    const std::uint8_t* src = rgba.data() + static_cast<std::size_t>(y) * width_px * 4;
    std::uint8_t* dst = rgb.mutable_data() + std::ptrdiff_t{y} * rgb.stride_bytes();
    for (int x = 0; x < width_px; ++x) {
      dst[3 * x + 0] = src[4 * x + 0];
      dst[3 * x + 1] = src[4 * x + 1];
      dst[3 * x + 2] = src[4 * x + 2];
    }
  }
  return rgb;
}

Image read_frame_rgb(DisplayOutput& output) {
  const int w = output.width_px(), h = output.height_px();
  std::vector<std::uint8_t> rgba(static_cast<std::size_t>(w) * h * 4);
  output.read_pixels(rgba);
  return rgba_to_rgb(rgba, w, h);
}

namespace detail {
std::unique_ptr<DisplayOutput> open_headless(const DisplayOptions& options) {
  return std::make_unique<HeadlessOutput>(options);
}
}  // namespace detail

std::unique_ptr<DisplayOutput> open_display(const DisplayOptions& options) {
  switch (options.backend) {
    case DisplayBackend::kKms:
      return detail::open_kms(options);
    case DisplayBackend::kHeadless:
      break;
  }
  return detail::open_headless(options);
}

}  // namespace wallar::display
