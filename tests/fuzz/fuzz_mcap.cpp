// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_mcap.cpp
/// @brief Fuzzes the MCAP reader and wallar's recording layout on it: the container (records,
/// chunks in every compression, CRCs, summary), then the recording (calibration metadata, JSON
/// messages, base64 PNGs, decoded).
#include <sys/mman.h>
#include <unistd.h>

#include <string>

#include "fuzz_common.hpp"
#include "wallar/drivers/recording/mcap.hpp"
#include "wallar/drivers/recording/mcap_recording.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wallar;
  // The reader takes a path: the input as an anonymous file.
  static const int fd = memfd_create("fuzz.mcap", MFD_CLOEXEC);
  if (fd < 0) __builtin_trap();
  if (ftruncate(fd, 0) != 0 || pwrite(fd, data, size, 0) != static_cast<ssize_t>(size)) {
    __builtin_trap();
  }
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  fuzz::expect_only_input_errors([&] {
    const auto file = recording::mcap::File::open(path);
    if (file->report().bytes_used > size) __builtin_trap();
    for (const auto& m : file->messages()) {
      if (file->read_message(m).size() != m.size) __builtin_trap();
    }
  });
  fuzz::expect_only_input_errors([&] {
    const recording::EurocRecording rec = recording::read_mcap_recording(path);
    for (int c = 0; c < 2; ++c) {
      for (const auto& f : rec.cams[static_cast<std::size_t>(c)].frames) {
        fuzz::expect_only_input_errors([&] { (void)recording::load_frame_gray(rec, c, f); });
      }
    }
  });
  return 0;
}
