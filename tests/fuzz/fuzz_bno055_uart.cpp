// SPDX-License-Identifier: Apache-2.0
/// @file fuzz_bno055_uart.cpp
/// @brief Fuzzes the BNO055 UART response parser with arbitrary bytes from the serial line,
/// arriving in arbitrary chunks: it must never read out of bounds, never hand out a read
/// response of the wrong length, and always make progress (no byte is parsed twice forever).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>

#include "wallar/drivers/imu/bno055_protocol.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wallar::drivers::bno055;  // NOLINT(google-build-using-namespace)
  if (size < 2) return 0;
  // The first byte sets the chunk size (how the tty hands bytes over), the second whether a
  // burst read (45 bytes) or a short read (1 byte) is outstanding.
  const std::size_t chunk = 1 + data[0] % 64;
  const std::size_t expected = (data[1] & 1) != 0 ? kBurstBytes : 1;
  data += 2;
  size -= 2;
  RxRing ring;
  std::array<std::uint8_t, kMaxLength> out{};
  std::size_t pushed = 0;
  std::size_t consumed_garbage = 0;
  for (std::size_t off = 0; off < size; off += chunk) {
    const std::size_t n = std::min(chunk, size - off);
    pushed += ring.push(std::span<const std::uint8_t>(data + off, n));
    // Parse until the parser needs more bytes; every other answer consumes at least a byte.
    for (int guard = 0;; ++guard) {
      if (guard > 4096) __builtin_trap();  // no progress: a parser loop
      const std::size_t before = ring.size();
      const Response r = parse_response(ring, expected, out);
      consumed_garbage += r.garbage_bytes;
      if (r.kind == ResponseKind::kIncomplete) break;
      if (ring.size() >= before) __builtin_trap();  // a complete answer consumed nothing
      if (r.kind == ResponseKind::kReadData) {
        // Only a frame of exactly the expected length is data.
        if (before < 2 + expected) __builtin_trap();
        if (expected == kBurstBytes) {
          const ScaledBurst s = scale_burst(
              unpack_burst(std::span<const std::uint8_t, kBurstBytes>(out.data(), kBurstBytes)),
              true);
          if (s.q_chipworld_body && std::abs(s.q_chipworld_body->norm() - 1.0) > 1e-9)
            __builtin_trap();
        }
      }
    }
    if (ring.size() > RxRing::capacity()) __builtin_trap();
  }
  if (consumed_garbage > pushed) __builtin_trap();
  return 0;
}
