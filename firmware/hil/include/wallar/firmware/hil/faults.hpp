// SPDX-License-Identifier: Apache-2.0
/// @file faults.hpp
/// @brief Fault injection for hardware-in-the-loop tests (`wallar run --fault`): a sink between
/// the replay and the pipeline that withholds or corrupts samples at planned sensor times.
/// Test tooling, not part of the product's modules.
///
/// Threading: parse_fault()/to_string() are pure; a FaultSink is called from the replay thread,
/// injected() from any thread; tracking_hangs()'s function from the tracking thread only,
/// render_hangs()'s from the render thread only.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "wallar/drivers/source/sensor_sink.hpp"

namespace wallar::firmware::hil {

/// A fault injected at a time of the (first) replay, in seconds from its first sample: into the
/// sensor streams ("camera-stall@1.0+0.5", "imu-unplug@0.4+0.6", "corrupt-frame@1.2") or into
/// the tracking thread, which then hangs before a frame ("tracking-hang@1.0+5": the supervisor
/// sees no heartbeat and withholds the watchdog), or into the render thread, which hangs in a
/// draw ("render-hang@1.0+5": as a page flip that never completes).
struct FaultSpec {
  enum class Kind : std::uint8_t {
    kCameraStall,
    kImuUnplug,
    kCorruptFrame,
    kTrackingHang,
    kRenderHang
  } kind = Kind::kCameraStall;
  double at_s = 0.0;
  double duration_s = 0.0;  //!< stalls and unplugs; corrupt-frame hits one frame
};
/// Parses a fault; throws InputError naming `text` when it is malformed.
FaultSpec parse_fault(const std::string& text);
std::string to_string(const FaultSpec& fault);

/// The tracking-hang faults of `faults` as ApplianceOptions::before_frame: the first frame at or
/// after each fault's time (from the first frame) sleeps for its duration, once. Empty when
/// there is none.
std::function<void(TimeNs t_ns)> tracking_hangs(const std::vector<FaultSpec>& faults);
/// The render-hang faults as ApplianceOptions::before_draw: the first draw at or after each
/// fault's time (from the first draw, in CLOCK_MONOTONIC) sleeps for its duration, once.
std::function<void(TimeNs now_ns)> render_hangs(const std::vector<FaultSpec>& faults);

/// Withholds (camera stall, IMU unplug) or garbles (corrupt frame: noise of the right size)
/// the samples the faults cover, and forwards the rest to `next`.
class FaultSink final : public source::SensorSink {
 public:
  FaultSink(source::SensorSink& next, std::vector<FaultSpec> faults);
  void on_imu(const ImuSample& s) override;
  void on_stereo(const StereoFrame& f) override;
  void on_unpaired(int cam, const CameraFrame& f) override { next_.on_unpaired(cam, f); }
  /// Frames and samples withheld or corrupted so far.
  [[nodiscard]] std::uint64_t injected() const { return injected_.load(); }

 private:
  bool active(FaultSpec::Kind kind, TimeNs t_ns) const;
  Image noise_like(const Image& like);

  source::SensorSink& next_;
  std::vector<FaultSpec> faults_;
  std::vector<bool> corrupted_;
  TimeNs t0_ns_ = -1;
  std::uint64_t lcg_ = 0x853c49e6748fea9bULL;
  std::atomic<std::uint64_t> injected_{0};
};

}  // namespace wallar::firmware::hil
