// SPDX-License-Identifier: Apache-2.0
/// @file bno055_registers.hpp
/// @brief Bosch BNO055 register map (page 0), bit fields and data scaling, from the datasheet.
///
/// Source: Bosch Sensortec BNO055 datasheet (BST-BNO055-DS000), section 4.2/4.3 "Register
/// description", section 3.3 "Operation modes", section 3.6.4 "Output data" (units and
/// LSB scaling) and section 4.7 "UART protocol". Data registers are little-endian int16,
/// LSB at the lower address. Only what the UART driver uses is listed.
///
/// Threading: constants only.
#pragma once

#include <cstdint>

namespace wallar::drivers::bno055 {

/// Page 0 registers (PAGE_ID = 0).
enum class Reg : std::uint8_t {
  kChipId = 0x00,  //!< reads kChipIdValue
  kAccId = 0x01,   //!< 0xFB
  kMagId = 0x02,   //!< 0x32
  kGyrId = 0x03,   //!< 0x0F
  kSwRevIdLsb = 0x04,
  kSwRevIdMsb = 0x05,
  kBlRevId = 0x06,
  kPageId = 0x07,         //!< register page select, 0 or 1
  kAccDataXLsb = 0x08,    //!< 0x08..0x0D accelerometer X, Y, Z (int16 LE)
  kMagDataXLsb = 0x0E,    //!< 0x0E..0x13 magnetometer X, Y, Z
  kGyrDataXLsb = 0x14,    //!< 0x14..0x19 gyroscope X, Y, Z
  kEulHeadingLsb = 0x1A,  //!< 0x1A..0x1F Euler heading, roll, pitch
  kQuaDataWLsb = 0x20,    //!< 0x20..0x27 quaternion W, X, Y, Z
  kLiaDataXLsb = 0x28,    //!< 0x28..0x2D linear acceleration
  kGrvDataXLsb = 0x2E,    //!< 0x2E..0x33 gravity vector
  kTemp = 0x34,           //!< int8 temperature
  kCalibStat = 0x35,      //!< CalibStat bits
  kStResult = 0x36,       //!< self-test result
  kIntSta = 0x37,
  kSysClkStatus = 0x38,
  kSysStatus = 0x39,   //!< SysStatus values
  kSysErr = 0x3A,      //!< SysErr values
  kUnitSel = 0x3B,     //!< UnitSel bits
  kOprMode = 0x3D,     //!< OprMode in bits [3:0]
  kPwrMode = 0x3E,     //!< PwrMode in bits [1:0]
  kSysTrigger = 0x3F,  //!< SysTrigger bits
  kTempSource = 0x40,  //!< bits [1:0]: 0 accelerometer, 1 gyroscope
  kAxisMapConfig = 0x41,
  kAxisMapSign = 0x42,
};

constexpr std::uint8_t reg_addr(Reg r) { return static_cast<std::uint8_t>(r); }

inline constexpr std::uint8_t kChipIdValue = 0xA0;  //!< CHIP_ID (0x00) reset value

/// CALIB_STAT (0x35): calibration status 0 (none) .. 3 (full) per subsystem.
namespace calib_stat {
inline constexpr std::uint8_t kSysShift = 6, kSysMask = (0x3 << 6);  //!< bits [7:6]
inline constexpr std::uint8_t kGyrShift = 4, kGyrMask = (0x3 << 4);  //!< bits [5:4]
inline constexpr std::uint8_t kAccShift = 2, kAccMask = (0x3 << 2);  //!< bits [3:2]
inline constexpr std::uint8_t kMagShift = 0, kMagMask = (0x3 << 0);  //!< bits [1:0]
}  // namespace calib_stat

/// SYS_STATUS (0x39) values.
enum class SysStatus : std::uint8_t {
  kIdle = 0,
  kSystemError = 1,
  kInitializingPeripherals = 2,
  kSystemInitialization = 3,
  kExecutingSelfTest = 4,
  kFusionRunning = 5,
  kRunningWithoutFusion = 6,
};

/// SYS_ERR (0x3A) values (meaningful when SYS_STATUS is kSystemError).
enum class SysErr : std::uint8_t {
  kNoError = 0,
  kPeripheralInit = 1,
  kSystemInit = 2,
  kSelfTestFailed = 3,
  kRegMapValueOutOfRange = 4,
  kRegMapAddressOutOfRange = 5,
  kRegMapWriteError = 6,
  kLowPowerModeNotAvailable = 7,
  kAccelPowerModeNotAvailable = 8,
  kFusionConfigError = 9,
  kSensorConfigError = 0xA,
};

/// UNIT_SEL (0x3B) bits; bits 6:5 and 3 are reserved.
namespace unit_sel {
inline constexpr std::uint8_t kOriAndroid = (1u << 7);  //!< bit 7: 0 Windows, 1 Android pitch sign
inline constexpr std::uint8_t kTempF = (1u << 4);       //!< bit 4: 0 deg C, 1 deg F
inline constexpr std::uint8_t kEulRad = (1u << 2);      //!< bit 2: 0 degrees, 1 radians
inline constexpr std::uint8_t kGyrRps = (1u << 1);      //!< bit 1: 0 dps, 1 rad/s ("rps")
inline constexpr std::uint8_t kAccMg = (1u << 0);       //!< bit 0: 0 m/s^2, 1 mg
inline constexpr std::uint8_t kDefinedMask = (kOriAndroid | kTempF | kEulRad | kGyrRps | kAccMg);
}  // namespace unit_sel

/// OPR_MODE (0x3D) bits [3:0] (datasheet table 3-5).
enum class OprMode : std::uint8_t {
  kConfig = 0x00,
  kAccOnly = 0x01,
  kMagOnly = 0x02,
  kGyroOnly = 0x03,
  kAccMag = 0x04,
  kAccGyro = 0x05,
  kMagGyro = 0x06,
  kAmg = 0x07,  //!< all three sensors, no fusion
  kImu = 0x08,
  kCompass = 0x09,
  kM4g = 0x0A,
  kNdofFmcOff = 0x0B,
  kNdof = 0x0C,  //!< 9-DOF fusion with fast magnetometer calibration
};
inline constexpr std::uint8_t kOprModeMask = (0xF << 0);  //!< bits [3:0]

/// PWR_MODE (0x3E) bits [1:0].
enum class PwrMode : std::uint8_t { kNormal = 0x00, kLowPower = 0x01, kSuspend = 0x02 };
inline constexpr std::uint8_t kPwrModeMask = (0x3 << 0);  //!< bits [1:0]

/// SYS_TRIGGER (0x3F) bits (self-clearing triggers except CLK_SEL).
namespace sys_trigger {
inline constexpr std::uint8_t kClkSel = (1u << 7);    //!< bit 7: 1 = external crystal
inline constexpr std::uint8_t kRstInt = (1u << 6);    //!< bit 6: reset interrupt status
inline constexpr std::uint8_t kRstSys = (1u << 5);    //!< bit 5: system reset
inline constexpr std::uint8_t kSelfTest = (1u << 0);  //!< bit 0: trigger self test
}  // namespace sys_trigger

/// Output data scaling (datasheet tables 3-17, 3-22, 3-28, 3-31, 3-37): LSB per unit.
namespace scale {
inline constexpr double kAccLsbPerMs2 = 100.0;     //!< 1 m/s^2 = 100 LSB
inline constexpr double kAccLsbPerMg = 1.0;        //!< 1 mg = 1 LSB
inline constexpr double kGyrLsbPerDps = 16.0;      //!< 1 dps = 16 LSB
inline constexpr double kGyrLsbPerRps = 900.0;     //!< 1 rad/s = 900 LSB
inline constexpr double kMagLsbPerUt = 16.0;       //!< 1 uT = 16 LSB
inline constexpr double kQuaLsbPerUnit = 16384.0;  //!< 1 (unit quaternion) = 2^14 LSB
inline constexpr double kTempLsbPerC = 1.0;        //!< 1 deg C = 1 LSB (int8)
}  // namespace scale

/// Mode switching times (datasheet table 3-6): from CONFIG to any mode 7 ms, from any mode
/// to CONFIG 19 ms. Power-on / reset to CONFIG mode: 650 ms (table 0-2 "start-up time").
inline constexpr std::int64_t kConfigToAnyNs = 7'000'000;
inline constexpr std::int64_t kAnyToConfigNs = 19'000'000;
inline constexpr std::int64_t kBootNs = 650'000'000;
/// Fusion output data rate in NDOF mode (table 3-14): 100 Hz.
inline constexpr double kFusionRateHz = 100.0;

}  // namespace wallar::drivers::bno055
