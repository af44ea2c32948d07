// SPDX-License-Identifier: Apache-2.0
/// @file faults.cpp
/// @brief Fault specs and the sink that injects them.
#include "wallar/firmware/hil/faults.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "wallar/core/error.hpp"

namespace wallar::firmware::hil {

FaultSpec parse_fault(const std::string& text) {
  auto fail = [&](const char* why) -> FaultSpec {
    throw InputError("--fault '" + text + "': " + why +
                     " (expected camera-stall@T+D, imu-unplug@T+D, corrupt-frame@T, "
                     "tracking-hang@T+D or render-hang@T+D, seconds)");
  };
  const std::size_t at = text.find('@');
  if (at == std::string::npos) return fail("no '@'");
  const std::string kind = text.substr(0, at);
  FaultSpec f;
  if (kind == "camera-stall") {
    f.kind = FaultSpec::Kind::kCameraStall;
  } else if (kind == "imu-unplug") {
    f.kind = FaultSpec::Kind::kImuUnplug;
  } else if (kind == "corrupt-frame") {
    f.kind = FaultSpec::Kind::kCorruptFrame;
  } else if (kind == "tracking-hang") {
    f.kind = FaultSpec::Kind::kTrackingHang;
  } else if (kind == "render-hang") {
    f.kind = FaultSpec::Kind::kRenderHang;
  } else {
    return fail("unknown fault");
  }
  const std::string rest = text.substr(at + 1);
  const std::size_t plus = rest.find('+');
  auto number = [&](const std::string& s, double& out) {
    const char* end = s.data() + s.size();
    const auto [ptr, ec] = std::from_chars(s.data(), end, out);
    if (ec != std::errc() || ptr != end || !std::isfinite(out) || out < 0.0) fail("bad number");
  };
  number(rest.substr(0, plus), f.at_s);
  if (f.kind == FaultSpec::Kind::kCorruptFrame) {
    if (plus != std::string::npos) fail("corrupt-frame takes no duration");
  } else {
    if (plus == std::string::npos) fail("missing '+DURATION'");
    number(rest.substr(plus + 1), f.duration_s);
    if (f.duration_s <= 0.0) fail("duration must be > 0");
  }
  return f;
}

std::string to_string(const FaultSpec& fault) {
  char buf[96];
  switch (fault.kind) {
    case FaultSpec::Kind::kCameraStall:
      std::snprintf(buf, sizeof buf, "camera-stall@%g+%g", fault.at_s, fault.duration_s);
      break;
    case FaultSpec::Kind::kImuUnplug:
      std::snprintf(buf, sizeof buf, "imu-unplug@%g+%g", fault.at_s, fault.duration_s);
      break;
    case FaultSpec::Kind::kCorruptFrame:
      std::snprintf(buf, sizeof buf, "corrupt-frame@%g", fault.at_s);
      break;
    case FaultSpec::Kind::kTrackingHang:
      std::snprintf(buf, sizeof buf, "tracking-hang@%g+%g", fault.at_s, fault.duration_s);
      break;
    case FaultSpec::Kind::kRenderHang:
      std::snprintf(buf, sizeof buf, "render-hang@%g+%g", fault.at_s, fault.duration_s);
      break;
  }
  return buf;
}

namespace {

// The faults of one hang kind as a function that sleeps once at the first call at or after
// each fault's time (from its first call).
std::function<void(TimeNs t_ns)> hangs_of(const std::vector<FaultSpec>& faults,
                                          FaultSpec::Kind kind) {
  struct Hang {
    DurationNs at_ns;
    DurationNs duration_ns;
    bool done;
  };
  std::vector<Hang> hangs;
  for (const FaultSpec& f : faults) {
    if (f.kind == kind) hangs.push_back({s_to_ns(f.at_s), s_to_ns(f.duration_s), false});
  }
  if (hangs.empty()) return {};
  // Called on one thread only: the state needs no lock.
  return [hangs = std::move(hangs), t0_ns = TimeNs{-1}](TimeNs t_ns) mutable {
    if (t0_ns < 0) t0_ns = t_ns;
    for (Hang& h : hangs) {
      if (h.done || t_ns - t0_ns < h.at_ns) continue;
      h.done = true;
      std::this_thread::sleep_for(std::chrono::nanoseconds(h.duration_ns));
    }
  };
}

}  // namespace

std::function<void(TimeNs t_ns)> tracking_hangs(const std::vector<FaultSpec>& faults) {
  return hangs_of(faults, FaultSpec::Kind::kTrackingHang);
}

std::function<void(TimeNs now_ns)> render_hangs(const std::vector<FaultSpec>& faults) {
  return hangs_of(faults, FaultSpec::Kind::kRenderHang);
}

FaultSink::FaultSink(source::SensorSink& next, std::vector<FaultSpec> faults)
    : next_(next), faults_(std::move(faults)), corrupted_(faults_.size(), false) {}

void FaultSink::on_imu(const ImuSample& s) {
  if (t0_ns_ < 0) t0_ns_ = s.t_ns;
  if (active(FaultSpec::Kind::kImuUnplug, s.t_ns)) {
    injected_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  next_.on_imu(s);
}

void FaultSink::on_stereo(const StereoFrame& f) {
  if (t0_ns_ < 0) t0_ns_ = f.t_ns;
  if (active(FaultSpec::Kind::kCameraStall, f.t_ns)) {
    injected_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  for (std::size_t i = 0; i < faults_.size(); ++i) {
    const FaultSpec& fault = faults_[i];
    if (fault.kind != FaultSpec::Kind::kCorruptFrame || corrupted_[i]) continue;
    if (f.t_ns < t0_ns_ + s_to_ns(fault.at_s)) continue;
    corrupted_[i] = true;
    injected_.fetch_add(1, std::memory_order_relaxed);
    StereoFrame bad = f;
    bad.left.image = noise_like(f.left.image);  // a garbled transfer: right size, no content
    next_.on_stereo(bad);
    return;
  }
  next_.on_stereo(f);
}

bool FaultSink::active(FaultSpec::Kind kind, TimeNs t_ns) const {
  for (const FaultSpec& fault : faults_) {
    if (fault.kind != kind) continue;
    const TimeNs begin = t0_ns_ + s_to_ns(fault.at_s);
    if (t_ns >= begin && t_ns < begin + s_to_ns(fault.duration_s)) return true;
  }
  return false;
}

Image FaultSink::noise_like(const Image& like) {
  Image out =
      Image::allocate(std::max(like.width(), 1), std::max(like.height(), 1), PixelFormat::kGray8);
  for (int y = 0; y < out.height(); ++y) {
    std::uint8_t* row = out.mutable_data() + std::ptrdiff_t{y} * out.stride_bytes();
    for (int x = 0; x < out.width(); ++x) {
      lcg_ = lcg_ * 6364136223846793005ULL + 1442695040888963407ULL;
      row[x] = static_cast<std::uint8_t>(lcg_ >> 56);
    }
  }
  return out;
}

}  // namespace wallar::firmware::hil
