// SPDX-License-Identifier: Apache-2.0
/// @file push_module.cpp
/// @brief Pushed samples -> time-ordered merge -> stereo pairs -> the pipeline.
#include "wallar/firmware/appliance/push_module.hpp"

#include <algorithm>
#include <cstdio>
#include <utility>

#include "wallar/firmware/appliance/thread_table.hpp"

namespace wallar::firmware {

PushModule::PushModule(const PushModuleOptions& options)
    : options_(options),
      imu_(std::max<std::size_t>(options.imu_capacity, 1)),
      images_(std::max<std::size_t>(options.image_capacity, 2)),
      pairer_(options.pair_tolerance_ns) {}

PushModule::~PushModule() = default;

PushResult PushModule::push_imu(const ImuSample& sample) {
  if (ended_.load(std::memory_order_acquire)) return PushResult::kClosed;
  if (sample.t_ns <= last_imu_t_ns_.load(std::memory_order_relaxed)) {
    imu_out_of_order_.fetch_add(1, std::memory_order_relaxed);
    return PushResult::kOutOfOrder;
  }
  ImuSample* slot = imu_.producer_slot();
  if (slot == nullptr) {
    imu_full_.fetch_add(1, std::memory_order_relaxed);
    return PushResult::kFull;
  }
  *slot = sample;
  imu_.push();
  last_imu_t_ns_.store(sample.t_ns, std::memory_order_release);
  imu_in_.fetch_add(1, std::memory_order_relaxed);
  pushed_.notify();
  return PushResult::kAccepted;
}

PushResult PushModule::push_image(int cam, CameraFrame frame) {
  if (ended_.load(std::memory_order_acquire)) return PushResult::kClosed;
  if (cam < 0 || cam > 1 ||
      frame.t_ns <=
          last_image_t_ns_[static_cast<std::size_t>(cam)].load(std::memory_order_relaxed)) {
    images_out_of_order_.fetch_add(1, std::memory_order_relaxed);
    return PushResult::kOutOfOrder;
  }
  QueuedImage* slot = images_.producer_slot();
  if (slot == nullptr) {
    images_full_.fetch_add(1, std::memory_order_relaxed);
    return PushResult::kFull;
  }
  const TimeNs t_ns = frame.t_ns;
  slot->cam = cam;
  slot->frame = std::move(frame);
  images_.push();
  last_image_t_ns_[static_cast<std::size_t>(cam)].store(t_ns, std::memory_order_release);
  images_in_.fetch_add(1, std::memory_order_relaxed);
  pushed_.notify();
  return PushResult::kAccepted;
}

void PushModule::end_of_stream() {
  ended_.store(true, std::memory_order_release);
  pushed_.notify();
}

PushCounters PushModule::counters() const {
  PushCounters c;
  c.imu_in = imu_in_.load();
  c.imu_full = imu_full_.load();
  c.imu_out_of_order = imu_out_of_order_.load();
  c.images_in = images_in_.load();
  c.images_full = images_full_.load();
  c.images_out_of_order = images_out_of_order_.load();
  c.imu_delivered = imu_delivered_.load();
  c.pairs_delivered = pairs_delivered_.load();
  c.unpaired = unpaired_.load();
  return c;
}

void PushModule::start(source::SensorSink& sink, drivers::ImuSampleSink& /*imu_sink*/,
                       bool realtime, const std::atomic<bool>& stop) {
  thread_ =
      std::make_unique<RtThread>(thread_spec("push", realtime, nullptr), [this, &sink, &stop] {
        const SetOnExit done(done_);
        run(sink, stop);
      });
  started_.store(true, std::memory_order_release);
}

void PushModule::run(source::SensorSink& sink, const std::atomic<bool>& stop) {
  TimeNs blocked_since_ns = -1;
  while (!stop.load(std::memory_order_acquire)) {
    // Read `ended` before the rings: a sample pushed before the end is then seen below.
    const bool ended = ended_.load(std::memory_order_acquire);
    ImuSample* imu = imu_.front();
    QueuedImage* image = images_.front();
    if (imu == nullptr && image == nullptr) {
      if (ended) break;
      pushed_.wait_for(10 * kNsPerMs);
      continue;
    }
    // The earlier of the two heads, IMU first on ties, once the other stream has been pushed
    // up to it (nothing earlier can come from it any more).
    bool take_imu = false;
    bool ready = ended;
    if (imu != nullptr && image != nullptr) {
      take_imu = imu->t_ns <= image->frame.t_ns;
      ready = true;
    } else if (imu != nullptr) {
      take_imu = true;
      const TimeNs images_up_to = std::min(last_image_t_ns_[0].load(std::memory_order_acquire),
                                           last_image_t_ns_[1].load(std::memory_order_acquire));
      ready = ready || images_up_to >= imu->t_ns;
    } else {
      ready = ready || !options_.imu ||
              last_imu_t_ns_.load(std::memory_order_acquire) >= image->frame.t_ns;
    }
    if (!ready) {
      // The other stream is silent: it holds this one for stall_ns at most.
      const TimeNs now = monotonic_now_ns();
      if (blocked_since_ns < 0) blocked_since_ns = now;
      if (now - blocked_since_ns < options_.stall_ns) {
        pushed_.wait_for(
            std::min<DurationNs>(options_.stall_ns - (now - blocked_since_ns), 10 * kNsPerMs));
        continue;
      }
    }
    blocked_since_ns = -1;
    if (take_imu) {
      const ImuSample s = *imu;
      imu_.pop();
      sink.on_imu(s);
      imu_delivered_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    const int cam = image->cam;
    CameraFrame frame = std::move(image->frame);
    image->frame = CameraFrame{};  // the slot holds no buffer while it waits for reuse
    images_.pop();
    sync::StereoPairer::Result r = pairer_.push(cam, std::move(frame));
    for (int c = 0; c < 2; ++c) {
      if (r.unpaired[static_cast<std::size_t>(c)]) {
        unpaired_.fetch_add(1, std::memory_order_relaxed);
        sink.on_unpaired(c, *r.unpaired[static_cast<std::size_t>(c)]);
      }
    }
    if (r.pair) {
      sink.on_stereo(*r.pair);  // every-frame modes: waits here until tracking took it
      pairs_delivered_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  auto rest = pairer_.flush();
  for (int c = 0; c < 2; ++c) {
    if (rest[static_cast<std::size_t>(c)]) {
      unpaired_.fetch_add(1, std::memory_order_relaxed);
      sink.on_unpaired(c, *rest[static_cast<std::size_t>(c)]);
    }
  }
}

bool PushModule::join_within(DurationNs timeout_ns) {
  return join_source_thread(thread_.get(), done_, timeout_ns);
}

std::string PushModule::describe() const {
  char buf[160];
  std::snprintf(buf, sizeof buf, "samples pushed by the caller (pairing within %.1f ms%s)",
                ns_to_s(options_.pair_tolerance_ns) * 1e3, options_.imu ? "" : ", no IMU");
  return buf;
}

std::exception_ptr PushModule::error() const { return source_thread_error(thread_.get()); }

}  // namespace wallar::firmware
