// SPDX-License-Identifier: Apache-2.0
/// @file v4l2_modes.cpp
/// @brief Capture-mode enumeration through the V4l2System seam.
#include "wallar/drivers/camera/v4l2_modes.hpp"

#include <fcntl.h>
#include <linux/videodev2.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "wallar/core/error.hpp"
#include "wallar/drivers/camera/v4l2_camera.hpp"

namespace wallar::drivers {
namespace {

double fps_of(const v4l2_fract& f) {
  return f.numerator > 0 ? static_cast<double>(f.denominator) / f.numerator : 0.0;
}

void add_rates(V4l2System& sys, int fd, V4l2Mode& mode) {
  for (std::uint32_t i = 0; i < 64; ++i) {
    v4l2_frmivalenum iv{};
    iv.index = i;
    iv.pixel_format = mode.fourcc;
    iv.width = static_cast<std::uint32_t>(mode.width_px);
    iv.height = static_cast<std::uint32_t>(mode.height_px);
    if (sys.ioctl(fd, VIDIOC_ENUM_FRAMEINTERVALS, &iv) < 0) return;
    if (iv.type == V4L2_FRMIVAL_TYPE_DISCRETE) {
      mode.fps.push_back(fps_of(iv.discrete));
      continue;
    }
    // Continuous or stepwise: the longest interval is the slowest rate.
    mode.fps = {fps_of(iv.stepwise.max), fps_of(iv.stepwise.min)};
    mode.fps_range = true;
    return;
  }
}

}  // namespace

std::vector<V4l2Mode> enumerate_v4l2_modes(V4l2System& sys, const std::string& path) {
  const int fd = sys.open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw DeviceError(path + ": cannot open: " + std::strerror(errno));
  std::vector<V4l2Mode> modes;
  for (std::uint32_t f = 0; f < 64; ++f) {
    v4l2_fmtdesc desc{};
    desc.index = f;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (sys.ioctl(fd, VIDIOC_ENUM_FMT, &desc) < 0) break;
    for (std::uint32_t s = 0; s < 256; ++s) {
      v4l2_frmsizeenum size{};
      size.index = s;
      size.pixel_format = desc.pixelformat;
      if (sys.ioctl(fd, VIDIOC_ENUM_FRAMESIZES, &size) < 0) break;
      V4l2Mode mode;
      mode.fourcc = desc.pixelformat;
      if (size.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
        mode.width_px = static_cast<int>(size.discrete.width);
        mode.height_px = static_cast<int>(size.discrete.height);
      } else {
        mode.size_range = true;
        mode.width_px = static_cast<int>(size.stepwise.max_width);
        mode.height_px = static_cast<int>(size.stepwise.max_height);
        mode.min_width_px = static_cast<int>(size.stepwise.min_width);
        mode.min_height_px = static_cast<int>(size.stepwise.min_height);
      }
      add_rates(sys, fd, mode);
      modes.push_back(std::move(mode));
      if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
    }
  }
  sys.close(fd);
  return modes;
}

bool offers_mode(const std::vector<V4l2Mode>& modes, std::uint32_t fourcc, int width_px,
                 int height_px, double fps) {
  for (const V4l2Mode& m : modes) {
    if (m.fourcc != fourcc) continue;
    const bool size_ok = m.size_range ? width_px >= m.min_width_px && width_px <= m.width_px &&
                                            height_px >= m.min_height_px && height_px <= m.height_px
                                      : width_px == m.width_px && height_px == m.height_px;
    if (!size_ok) continue;
    if (!(fps > 0.0) || m.fps.empty()) return true;  // no rate asked, or none enumerated
    if (m.fps_range) {
      if (fps >= m.fps[0] * 0.99 && fps <= m.fps[1] * 1.01) return true;
      continue;
    }
    for (const double r : m.fps) {
      if (std::abs(r - fps) <= 0.01 * fps) return true;
    }
  }
  return false;
}

std::string describe_modes(const std::vector<V4l2Mode>& modes, std::size_t max) {
  std::string out;
  for (std::size_t i = 0; i < modes.size(); ++i) {
    if (i == max) {
      out += ", ...";
      break;
    }
    const V4l2Mode& m = modes[i];
    char buf[96];
    if (m.size_range) {
      std::snprintf(buf, sizeof buf, "%s%s %dx%d..%dx%d", i > 0 ? ", " : "",
                    fourcc_to_string(m.fourcc).c_str(), m.min_width_px, m.min_height_px, m.width_px,
                    m.height_px);
    } else {
      std::snprintf(buf, sizeof buf, "%s%s %dx%d", i > 0 ? ", " : "",
                    fourcc_to_string(m.fourcc).c_str(), m.width_px, m.height_px);
    }
    out += buf;
    if (!m.fps.empty()) {
      out += " @ ";
      for (std::size_t r = 0; r < m.fps.size(); ++r) {
        std::snprintf(buf, sizeof buf, "%s%g", r > 0 ? (m.fps_range ? "-" : "/") : "", m.fps[r]);
        out += buf;
      }
      out += " Hz";
    }
  }
  return out.empty() ? "nothing" : out;
}

}  // namespace wallar::drivers
