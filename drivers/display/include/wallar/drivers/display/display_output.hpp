// SPDX-License-Identifier: Apache-2.0
/// @file display_output.hpp
/// @brief Where the headset view is drawn: an EGL + OpenGL ES 3 context bound to a DRM/KMS
/// output (the standalone headset, no X or Wayland) or to an off-screen pbuffer (headless:
/// tests, `wallar render`, Mesa's llvmpipe when there is no GPU).
///
/// Backends:
///  - headless: EGL on Mesa's surfaceless platform (EGL_MESA_platform_surfaceless), an RGBA8
///    pbuffer of the requested size; present() finishes the frame (glFinish) and returns.
///  - kms: the card's connector (by name, e.g. "HDMI-A-1", or the first connected one) in the
///    mode matching the requested size (else its preferred mode), a GBM surface of scan-out
///    buffers, EGL on EGL_PLATFORM_GBM_KHR; present() swaps, page-flips the new front buffer
///    and waits for the flip's vblank event (frames paced by the display).
///
/// Errors: opening throws DisplayError with one line naming the device and what failed.
/// present() returns false with last_error() set when the output went away (GPU reset,
/// connector unplugged, flip timeout); the caller closes and re-opens later (the renderer
/// never blocks tracking: it runs on its own thread and draws the newest snapshot).
///
/// Threading: an output's context is current on the thread that opened it; every call on
/// the output (and every GL call of the renderer on it) must come from that thread.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>

#include "wallar/core/image.hpp"
#include "wallar/core/time.hpp"

namespace wallar::display {

/// A display that could not be opened or failed; what() is one line naming the device.
class DisplayError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class DisplayBackend : std::uint8_t { kHeadless, kKms };

struct DisplayOptions {
  DisplayBackend backend = DisplayBackend::kHeadless;
  std::string card = "/dev/dri/card0";  //!< kms: the DRM device
  std::string connector;                //!< kms: "HDMI-A-1", "DSI-1", ...; empty = first connected
  int width_px = 1280;                  //!< wanted size (kms: a mode of this size if there is one)
  int height_px = 720;
  bool vsync = true;  //!< kms: wait for the flip's vblank event
};

/// Parses "headless" or "kms"; throws DisplayError naming the value otherwise.
DisplayBackend parse_display_backend(const std::string& name);

class DisplayOutput {
 public:
  virtual ~DisplayOutput() = default;
  DisplayOutput() = default;
  DisplayOutput(const DisplayOutput&) = delete;
  DisplayOutput& operator=(const DisplayOutput&) = delete;

  /// Size of the drawable in pixels (the KMS mode's size may differ from the one asked for).
  [[nodiscard]] virtual int width_px() const = 0;
  [[nodiscard]] virtual int height_px() const = 0;
  /// "headless 1280x720 (llvmpipe ...)" or "kms /dev/dri/card1 HDMI-A-1 2560x1440@60".
  [[nodiscard]] virtual std::string describe() const = 0;
  /// Shows the frame drawn into the default framebuffer since the last present. Returns false
  /// (and sets last_error()) when the output is lost; `t_ns` receives the CLOCK_MONOTONIC time
  /// the frame reached the display (kms: the flip event's time; headless: when it finished).
  [[nodiscard]] virtual bool present(TimeNs& t_ns) = 0;
  /// Reads the default framebuffer back as RGBA8, top row first (tests, PNG frames).
  /// `rgba` must hold width_px() * height_px() * 4 bytes.
  virtual void read_pixels(std::span<std::uint8_t> rgba) = 0;
  [[nodiscard]] virtual const std::string& last_error() const = 0;
  /// Frames the display confirmed on screen: kms counts the mode set and every page flip whose
  /// event arrived; headless shows nothing (0).
  [[nodiscard]] virtual std::uint64_t frames_on_screen() const { return 0; }
};

/// The frame last drawn (before present(); headless: also after), as a fresh 8-bit RGB image
/// (tests); allocates.
Image read_frame_rgb(DisplayOutput& output);
/// Top-row-first RGBA pixels of a width x height frame as a fresh 8-bit RGB image; allocates.
Image rgba_to_rgb(std::span<const std::uint8_t> rgba, int width_px, int height_px);

/// Opens the output and makes its GL ES 3 context current on the calling thread.
std::unique_ptr<DisplayOutput> open_display(const DisplayOptions& options);

namespace detail {
std::unique_ptr<DisplayOutput> open_headless(const DisplayOptions& options);
std::unique_ptr<DisplayOutput> open_kms(const DisplayOptions& options);
}  // namespace detail

}  // namespace wallar::display
