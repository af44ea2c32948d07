// SPDX-License-Identifier: Apache-2.0
/// @file bench_capture.cpp
/// @brief Capture-to-pair latency on the fake V4L2 device: the CPU time from two frames being
/// ready in their kernel buffers (the fake's poll returns them) to the pair arriving in the
/// tracker's mailbox: DQBUF, stamping, sequence checks, conversion to gray, pairing, posting,
/// and the re-queue of the buffers. The fake's virtual clock makes frame waits free, so the
/// time per iteration is the capture path's own cost. Not measured here: the kernel's wake-up
/// latency (poll returning after the interrupt), which only the real device shows.
#include <benchmark/benchmark.h>

#include "unit/fake_v4l2.hpp"
#include "wallar/core/mailbox.hpp"
#include "wallar/drivers/camera/stereo_capture.hpp"

namespace wallar::test {
namespace {

void BM_CaptureToPair(benchmark::State& state) {
  const auto format = static_cast<drivers::CameraPixelFormat>(state.range(0));
  const int width = static_cast<int>(state.range(1));
  const int height = static_cast<int>(state.range(2));
  FakeCameraSpec spec;
  spec.width_px = width;
  spec.height_px = height;
  spec.render_every_frame = false;
  FakeV4l2 sys;
  sys.add_device("/dev/video0", spec);
  sys.add_device("/dev/video2", spec);
  std::array<drivers::V4l2CameraConfig, 2> configs;
  configs[0].device = "/dev/video0";
  configs[1].device = "/dev/video2";
  for (auto& c : configs) {
    c.width_px = width;
    c.height_px = height;
    c.format = format;
  }
  MailboxSink sink;
  drivers::StereoCapture capture(sys, configs, sink);
  capture.start();
  StereoFrame taken;
  for (auto _ : state) {
    do {
      state.PauseTiming();
      capture.run_once(0);       // re-queues what the consumer returned; no frame is due yet
      sys.poll(nullptr, 0, 34);  // both frames become ready (the next frame time)
      state.ResumeTiming();
      capture.run_once(0);
    } while (!sink.box.take(taken));
    benchmark::DoNotOptimize(taken.left.image.data());
    taken = StereoFrame{};
  }
  state.counters["pairs"] = static_cast<double>(capture.pairing().pairs);
  state.counters["dropped"] = static_cast<double>(capture.camera(0).counters().dropped +
                                                  capture.camera(1).counters().dropped);
  state.SetLabel(drivers::fourcc_to_string(drivers::fourcc_of(format)));
}
BENCHMARK(BM_CaptureToPair)
    ->ArgNames({"format", "w", "h"})
    ->Args({static_cast<int>(drivers::CameraPixelFormat::kGrey), 752, 480})
    ->Args({static_cast<int>(drivers::CameraPixelFormat::kGrey), 640, 480})
    ->Args({static_cast<int>(drivers::CameraPixelFormat::kYuyv), 640, 480})
    ->Args({static_cast<int>(drivers::CameraPixelFormat::kMjpg), 640, 480})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace wallar::test

BENCHMARK_MAIN();
