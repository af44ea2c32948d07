// SPDX-License-Identifier: Apache-2.0
/// @file replay_source.cpp
/// @brief Time-ordered, paced playback of an EuRoC recording.
#include "wallar/drivers/source/replay_source.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>

namespace wallar::source {
namespace {

// Sleeps until an absolute CLOCK_MONOTONIC time; returns early only when asked to stop.
void sleep_until_ns(TimeNs deadline_ns, const std::atomic<bool>& stop) {
  constexpr DurationNs kSlice = 50 * kNsPerMs;  // wake now and then to honour stop
  while (!stop.load(std::memory_order_relaxed)) {
    const TimeNs now = monotonic_now_ns();
    if (now >= deadline_ns) return;
    const timespec ts = ns_to_timespec(std::min(deadline_ns, now + kSlice));
    const int rc = clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    if (rc != 0 && rc != EINTR) return;
  }
}

}  // namespace

ReplaySource::ReplaySource(const recording::EurocRecording& recording, ReplayOptions options)
    : rec_(recording), options_(options) {
  if (options_.pair_tolerance_ns >= 0) {
    tolerance_ns_ = options_.pair_tolerance_ns;
  } else {
    const double rate_hz = std::max(rec_.cams[0].calib.rate_hz, rec_.cams[1].calib.rate_hz);
    tolerance_ns_ = rate_hz > 0.0 ? static_cast<DurationNs>(0.5e9 / rate_hz) : 5 * kNsPerMs;
  }
}

ReplayStats ReplaySource::run(SensorSink& sink, const std::atomic<bool>& stop) {
  ReplayStats stats;
  stats.pair_tolerance_ns = tolerance_ns_;
  sync::StereoPairer pairer(tolerance_ns_);
  const auto& imu = rec_.imu;
  const auto& f0 = rec_.cams[0].frames;
  const auto& f1 = rec_.cams[1].frames;

  // The recording starts at its earliest sample of any stream.
  TimeNs t0 = std::numeric_limits<TimeNs>::max();
  if (!imu.empty()) t0 = std::min(t0, imu.front().t_ns);
  if (!f0.empty()) t0 = std::min(t0, f0.front().t_ns);
  if (!f1.empty()) t0 = std::min(t0, f1.front().t_ns);
  if (t0 == std::numeric_limits<TimeNs>::max()) return stats;
  const TimeNs t_begin = t0 + options_.start_offset_ns;

  auto first_at_or_after = [t_begin](const auto& v) {
    return static_cast<std::size_t>(
        std::lower_bound(v.begin(), v.end(), t_begin,
                         [](const auto& e, TimeNs t) { return e.t_ns < t; }) -
        v.begin());
  };
  std::size_t i_imu = first_at_or_after(imu);
  std::array<std::size_t, 2> i_cam{first_at_or_after(f0), first_at_or_after(f1)};

  const TimeNs wall_start = monotonic_now_ns();
  std::uint32_t to_skip = 0;
  bool first = true;

  auto deliver_pair = [&](StereoFrame&& pair) {
    if (to_skip > 0) {
      --to_skip;
      ++stats.pairs_skipped;
      return;
    }
    sink.on_stereo(pair);
    ++stats.pairs_delivered;
    to_skip = options_.skip;
  };
  auto handle = [&](sync::StereoPairer::Result&& r) {
    for (int c = 0; c < 2; ++c) {
      if (r.unpaired[static_cast<std::size_t>(c)])
        sink.on_unpaired(c, *r.unpaired[static_cast<std::size_t>(c)]);
    }
    if (r.pair) deliver_pair(std::move(*r.pair));
  };

  for (;;) {
    if (stop.load(std::memory_order_relaxed)) {
      stats.stopped = true;
      break;
    }
    // The next event in time: IMU first on ties (a frame's IMU is there before the frame).
    TimeNs t_next = std::numeric_limits<TimeNs>::max();
    int which = -1;  // 0, 1 = camera, 2 = IMU
    if (i_imu < imu.size()) {
      t_next = imu[i_imu].t_ns;
      which = 2;
    }
    for (int c = 0; c < 2; ++c) {
      const auto& frames = rec_.cams[static_cast<std::size_t>(c)].frames;
      const std::size_t i = i_cam[static_cast<std::size_t>(c)];
      if (i < frames.size() && frames[i].t_ns < t_next) {
        t_next = frames[i].t_ns;
        which = c;
      }
    }
    if (which < 0) break;
    if (first) {
      stats.first_t_ns = t_next;
      first = false;
    }
    stats.last_t_ns = t_next;

    if (options_.rate > 0.0) {
      const auto offset = static_cast<DurationNs>(
          std::llround(static_cast<double>(t_next - t_begin) / options_.rate));
      const TimeNs due = wall_start + offset;
      sleep_until_ns(due, stop);
      stats.max_lateness_ns = std::max(stats.max_lateness_ns, monotonic_now_ns() - due);
    }

    if (which == 2) {
      ImuSample s = imu[i_imu++];
      s.publish_t_ns = monotonic_now_ns();
      sink.on_imu(s);
      ++stats.imu_samples;
      continue;
    }
    const auto& cam = rec_.cams[static_cast<std::size_t>(which)];
    const recording::FrameEntry& entry = cam.frames[i_cam[static_cast<std::size_t>(which)]];
    CameraFrame frame;
    frame.t_ns = entry.t_ns;
    frame.sequence = i_cam[static_cast<std::size_t>(which)]++;
    if (options_.with_images) {
      frame.image = recording::load_frame_gray(rec_, which, entry);
    }
    frame.publish_t_ns = monotonic_now_ns();
    ++stats.frames[static_cast<std::size_t>(which)];
    handle(pairer.push(which, std::move(frame)));
  }
  auto rest = pairer.flush();
  for (int c = 0; c < 2; ++c) {
    if (rest[static_cast<std::size_t>(c)]) sink.on_unpaired(c, *rest[static_cast<std::size_t>(c)]);
  }
  stats.pairing = pairer.stats();
  stats.wall_time_ns = monotonic_now_ns() - wall_start;
  return stats;
}

}  // namespace wallar::source
