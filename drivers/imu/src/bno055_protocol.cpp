// SPDX-License-Identifier: Apache-2.0
/// @file bno055_protocol.cpp
/// @brief BNO055 UART framing, resync and data scaling.
#include "wallar/drivers/imu/bno055_protocol.hpp"

#include <numbers>

namespace wallar::drivers::bno055 {

std::size_t encode_read(std::span<std::uint8_t, kReadRequestBytes> out, Reg reg, std::size_t len) {
  if (len == 0 || len > kMaxLength) return 0;
  out[0] = kRequestStart;
  out[1] = kCmdRead;
  out[2] = reg_addr(reg);
  out[3] = static_cast<std::uint8_t>(len);  // 128 is sent as 0x80
  return kReadRequestBytes;
}

std::size_t encode_write(std::span<std::uint8_t> out, Reg reg, std::span<const std::uint8_t> data) {
  if (data.empty() || data.size() > kMaxLength || out.size() < 4 + data.size()) return 0;
  out[0] = kRequestStart;
  out[1] = kCmdWrite;
  out[2] = reg_addr(reg);
  out[3] = static_cast<std::uint8_t>(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) out[4 + i] = data[i];
  return 4 + data.size();
}

Response parse_response(RxRing& ring, std::size_t expected_len, std::span<std::uint8_t> out) {
  Response r;
  r.garbage_bytes =
      ring.resync([](std::uint8_t b) { return b == kResponseRead || b == kResponseStatus; });
  if (ring.size() < 2) return r;  // kIncomplete
  if (ring[0] == kResponseStatus) {
    const std::uint8_t code = ring[1];
    if (code == 0 || code > kMaxStatusCode) {
      ring.drop(1);  // not a status frame: the 0xEE was data or noise
      r.kind = ResponseKind::kBadFrame;
      return r;
    }
    ring.consume(2);
    r.kind = ResponseKind::kStatus;
    r.status = static_cast<UartStatus>(code);
    return r;
  }
  // 0xBB len data[len]. len 0 encodes nothing valid; the chip sends 1..128.
  const std::size_t len = ring[1];
  if (expected_len == 0 || len != expected_len || out.size() < len) {
    ring.drop(1);
    r.kind = ResponseKind::kBadFrame;
    return r;
  }
  if (ring.size() < 2 + len) return r;  // partial frame: wait for the rest
  ring.copy_out(2, out.first(len));
  ring.consume(2 + len);
  r.kind = ResponseKind::kReadData;
  return r;
}

RawBurst unpack_burst(std::span<const std::uint8_t, kBurstBytes> bytes) {
  const auto at = [&bytes](Reg reg) { return bytes.data() + (reg_addr(reg) - kBurstFirst); };
  RawBurst raw;
  for (int i = 0; i < 3; ++i) {
    raw.acc[i] = le_i16(at(Reg::kAccDataXLsb) + 2 * i);
    raw.mag[i] = le_i16(at(Reg::kMagDataXLsb) + 2 * i);
    raw.gyr[i] = le_i16(at(Reg::kGyrDataXLsb) + 2 * i);
  }
  for (int i = 0; i < 4; ++i) raw.qua[i] = le_i16(at(Reg::kQuaDataWLsb) + 2 * i);
  raw.temp = static_cast<std::int8_t>(*at(Reg::kTemp));
  return raw;
}

ScaledBurst scale_burst(const RawBurst& raw, bool gyro_rps) {
  constexpr double kDegToRad = std::numbers::pi / 180.0;
  const double gyro_scale =
      gyro_rps ? 1.0 / scale::kGyrLsbPerRps : kDegToRad / scale::kGyrLsbPerDps;
  ScaledBurst s;
  for (int i = 0; i < 3; ++i) {
    s.accel_m_s2[i] = raw.acc[i] / scale::kAccLsbPerMs2;
    s.gyro_rad_s[i] = raw.gyr[i] * gyro_scale;
    s.mag_uT[i] = raw.mag[i] / scale::kMagLsbPerUt;
  }
  if (raw.qua[0] != 0 || raw.qua[1] != 0 || raw.qua[2] != 0 || raw.qua[3] != 0) {
    const Eigen::Quaterniond q(
        raw.qua[0] / scale::kQuaLsbPerUnit, raw.qua[1] / scale::kQuaLsbPerUnit,
        raw.qua[2] / scale::kQuaLsbPerUnit, raw.qua[3] / scale::kQuaLsbPerUnit);
    s.q_chipworld_body = q.normalized();
  }
  s.temperature_c = raw.temp / scale::kTempLsbPerC;
  return s;
}

}  // namespace wallar::drivers::bno055
