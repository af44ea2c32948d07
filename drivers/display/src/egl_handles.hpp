// SPDX-License-Identifier: Apache-2.0
/// @file egl_handles.hpp
/// @brief The EGL objects of one display output, released in reverse order (also when a
/// constructor throws half-way), leaving no context current. Internal to drivers/display.
///
/// Threading: destroy on the thread that made the context current.
#pragma once

#include <EGL/egl.h>

namespace wallar::display::detail {

struct EglHandles {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface surface = EGL_NO_SURFACE;
  /// false: leave the display initialised (the process-wide surfaceless display, whose driver
  /// would otherwise be unloaded and loaded again, with its JIT, for every output).
  bool terminate = true;
  EglHandles() = default;
  EglHandles(const EglHandles&) = delete;
  EglHandles& operator=(const EglHandles&) = delete;
  ~EglHandles() {
    if (display == EGL_NO_DISPLAY) return;
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (surface != EGL_NO_SURFACE) eglDestroySurface(display, surface);
    if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
    if (terminate) eglTerminate(display);
    eglReleaseThread();
  }
};

}  // namespace wallar::display::detail
