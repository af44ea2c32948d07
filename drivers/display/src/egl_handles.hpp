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
  EglHandles() = default;
  EglHandles(const EglHandles&) = delete;
  EglHandles& operator=(const EglHandles&) = delete;
  ~EglHandles() {
    if (display == EGL_NO_DISPLAY) return;
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (surface != EGL_NO_SURFACE) eglDestroySurface(display, surface);
    if (context != EGL_NO_CONTEXT) eglDestroyContext(display, context);
    eglTerminate(display);
    eglReleaseThread();
  }
};

}  // namespace wallar::display::detail
