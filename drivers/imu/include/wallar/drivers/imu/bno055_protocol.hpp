// SPDX-License-Identifier: Apache-2.0
/// @file bno055_protocol.hpp
/// @brief BNO055 UART protocol (datasheet section 4.7): request encoding, response parsing
/// with resync, and the byte reassembly and scaling of the data registers.
///
/// Requests (host -> chip):
///   write: 0xAA 0x00 reg len data[len]      read: 0xAA 0x01 reg len
/// Responses (chip -> host):
///   read success: 0xBB len data[len]        write ack / read failure: 0xEE status
/// The protocol has no checksum: a response is accepted only if its length byte equals the
/// length that was asked for; anything else is a bad frame and the caller resynchronises.
///
/// Threading: pure functions on caller-owned buffers; nothing allocates.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

#include "wallar/drivers/imu/bno055_registers.hpp"
#include "wallar/drivers/serial/byte_ring.hpp"

namespace wallar::drivers::bno055 {

inline constexpr std::uint8_t kRequestStart = 0xAA;  //!< first byte of every request
inline constexpr std::uint8_t kCmdWrite = 0x00;
inline constexpr std::uint8_t kCmdRead = 0x01;
inline constexpr std::uint8_t kResponseRead = 0xBB;    //!< read success: 0xBB len data
inline constexpr std::uint8_t kResponseStatus = 0xEE;  //!< 0xEE status
inline constexpr std::size_t kMaxLength = 128;         //!< longest read/write of one request
inline constexpr std::size_t kReadRequestBytes = 4;

/// The status byte of a 0xEE response (datasheet table 4-8 / 4-9).
enum class UartStatus : std::uint8_t {
  kWriteSuccess = 0x01,
  kReadFail = 0x02,
  kWriteFail = 0x03,
  kRegmapInvalidAddress = 0x04,
  kRegmapWriteDisabled = 0x05,
  kWrongStartByte = 0x06,
  kBusOverRunError = 0x07,  //!< the chip's known answer under load: retry the read
  kMaxLengthError = 0x08,
  kMinLengthError = 0x09,
  kReceiveCharacterTimeout = 0x0A,
};
inline constexpr std::uint8_t kMaxStatusCode = 0x0A;

constexpr std::string_view to_string(UartStatus s) {
  switch (s) {
    case UartStatus::kWriteSuccess:
      return "WRITE_SUCCESS";
    case UartStatus::kReadFail:
      return "READ_FAIL";
    case UartStatus::kWriteFail:
      return "WRITE_FAIL";
    case UartStatus::kRegmapInvalidAddress:
      return "REGMAP_INVALID_ADDRESS";
    case UartStatus::kRegmapWriteDisabled:
      return "REGMAP_WRITE_DISABLED";
    case UartStatus::kWrongStartByte:
      return "WRONG_START_BYTE";
    case UartStatus::kBusOverRunError:
      return "BUS_OVER_RUN_ERROR";
    case UartStatus::kMaxLengthError:
      return "MAX_LENGTH_ERROR";
    case UartStatus::kMinLengthError:
      return "MIN_LENGTH_ERROR";
    case UartStatus::kReceiveCharacterTimeout:
      return "RECEIVE_CHARACTER_TIMEOUT";
  }
  return "?";
}

/// Encodes a read request into out; returns its length (4), or 0 when len is 0 or above
/// kMaxLength.
std::size_t encode_read(std::span<std::uint8_t, kReadRequestBytes> out, Reg reg, std::size_t len);
/// Encodes a write request of data into out; returns its length (4 + data.size()), or 0 when
/// data is empty, longer than kMaxLength, or out is too small.
std::size_t encode_write(std::span<std::uint8_t> out, Reg reg, std::span<const std::uint8_t> data);

/// The receive ring the parser works on (two longest frames fit).
using RxRing = ByteRing<512>;

enum class ResponseKind : std::uint8_t {
  kIncomplete,  //!< not enough bytes yet (a partial frame stays in the ring)
  kReadData,    //!< 0xBB len data: data copied out, frame consumed
  kStatus,      //!< 0xEE status: a known status code, frame consumed
  kBadFrame,    //!< wrong length or unknown status: the start byte was dropped
};

struct Response {
  ResponseKind kind = ResponseKind::kIncomplete;
  UartStatus status = UartStatus::kWriteSuccess;  //!< valid for kStatus
  std::size_t garbage_bytes = 0;  //!< bytes dropped before a start byte in this call
};

/// Parses one response from the front of `ring`. Bytes before a 0xBB/0xEE start byte are
/// dropped (counted in garbage_bytes and in the ring). A read response is accepted only if
/// its length equals expected_len (0: no read outstanding, so any 0xBB is a bad frame); the
/// data goes to out (out.size() >= expected_len).
Response parse_response(RxRing& ring, std::size_t expected_len, std::span<std::uint8_t> out);

/// Little-endian int16 at p[0] (LSB), p[1] (MSB).
constexpr std::int16_t le_i16(const std::uint8_t* p) {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0]) |
                                   static_cast<std::uint16_t>((static_cast<unsigned>(p[1]) << 8)));
}

/// The driver's burst read: ACC_DATA_X_LSB (0x08) .. TEMP (0x34) inclusive.
inline constexpr std::uint8_t kBurstFirst = reg_addr(Reg::kAccDataXLsb);
inline constexpr std::uint8_t kBurstLast = reg_addr(Reg::kTemp);
inline constexpr std::size_t kBurstBytes = kBurstLast - kBurstFirst + 1;  // 45
static_assert(kBurstBytes == 45 && kBurstBytes <= kMaxLength);

/// Raw register values of one burst, LSB units.
struct RawBurst {
  std::array<std::int16_t, 3> acc{};
  std::array<std::int16_t, 3> mag{};
  std::array<std::int16_t, 3> gyr{};
  std::array<std::int16_t, 4> qua{};  //!< w, x, y, z
  std::int8_t temp = 0;
};

/// Reassembles the registers of a kBurstBytes burst starting at ACC_DATA_X_LSB.
RawBurst unpack_burst(std::span<const std::uint8_t, kBurstBytes> bytes);

/// The burst in SI units (UNIT_SEL: m/s^2, deg C; gyro in rad/s or dps per gyro_rps).
struct ScaledBurst {
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d mag_uT = Eigen::Vector3d::Zero();
  /// Fused attitude, normalised; nullopt when the chip reports the all-zero quaternion
  /// (fusion not running yet): no attitude is invented.
  std::optional<Eigen::Quaterniond> q_chipworld_body;
  double temperature_c = 0.0;
};

ScaledBurst scale_burst(const RawBurst& raw, bool gyro_rps);

}  // namespace wallar::drivers::bno055
