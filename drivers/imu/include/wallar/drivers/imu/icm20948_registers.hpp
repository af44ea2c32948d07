// SPDX-License-Identifier: Apache-2.0
/// @file icm20948_registers.hpp
/// @brief InvenSense ICM-20948 register map (4 user banks) and the AK09916 magnetometer's,
/// from the datasheet DS-000189 rev 1.3, section 7 (register map) and 8 (descriptions),
/// and the AK09916 datasheet (AKM, 2015), section 9.
///
/// Every register is addressed as (bank, reg): the bank is selected with REG_BANK_SEL (0x7F,
/// present in every bank) bits [5:4]. One enum class per bank keeps a bank-2 register from
/// being written while bank 0 is selected. Bit enums give the datasheet bit range in a comment.
///
/// Threading: constants only.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wallar::drivers::icm20948 {

inline constexpr std::uint8_t kWhoAmIValue = 0xEA;         //!< DS-000189 §8.1 WHO_AM_I
inline constexpr std::uint8_t kPwrMgmt1ResetValue = 0x41;  //!< §8.4: SLEEP | CLKSEL=1
inline constexpr std::size_t kFifoSize = 512;              //!< §4.19 FIFO, bytes (no DMP)
inline constexpr double kBaseRateHz = 1125.0;  //!< §8.x ODR = 1.125 kHz / (1 + SMPLRT_DIV)

enum class Bank : std::uint8_t { k0 = 0, k1 = 1, k2 = 2, k3 = 3 };

/// REG_BANK_SEL, the same address in every bank (§8.65).
inline constexpr std::uint8_t kRegBankSel = 0x7F;
/// REG_BANK_SEL value: USER_BANK in bits [5:4].
constexpr std::uint8_t bank_sel_value(Bank b) {
  return static_cast<std::uint8_t>((static_cast<std::uint8_t>(b) & 0x03u) << 4);
}

/// USER BANK 0 (§7.1, §8.1 - §8.65).
enum class Reg0 : std::uint8_t {
  WHO_AM_I = 0x00,
  USER_CTRL = 0x03,
  LP_CONFIG = 0x05,
  PWR_MGMT_1 = 0x06,
  PWR_MGMT_2 = 0x07,
  INT_PIN_CFG = 0x0F,
  INT_ENABLE = 0x10,
  INT_ENABLE_1 = 0x11,
  INT_ENABLE_2 = 0x12,
  INT_ENABLE_3 = 0x13,
  I2C_MST_STATUS = 0x17,
  INT_STATUS = 0x19,
  INT_STATUS_1 = 0x1A,
  INT_STATUS_2 = 0x1B,
  INT_STATUS_3 = 0x1C,
  ACCEL_XOUT_H = 0x2D,  // ..0x32, then GYRO_XOUT_H 0x33..0x38
  GYRO_XOUT_H = 0x33,
  TEMP_OUT_H = 0x39,
  TEMP_OUT_L = 0x3A,
  EXT_SLV_SENS_DATA_00 = 0x3B,  // ..EXT_SLV_SENS_DATA_23 = 0x52
  FIFO_EN_1 = 0x66,
  FIFO_EN_2 = 0x67,
  FIFO_RST = 0x68,
  FIFO_MODE = 0x69,
  FIFO_COUNTH = 0x70,
  FIFO_COUNTL = 0x71,
  FIFO_R_W = 0x72,
  DATA_RDY_STATUS = 0x74,
  FIFO_CFG = 0x76,
};

/// USER BANK 1 (§7.2): self-test factory trim, accel offsets, time base.
enum class Reg1 : std::uint8_t {
  SELF_TEST_X_GYRO = 0x02,
  SELF_TEST_Y_GYRO = 0x03,
  SELF_TEST_Z_GYRO = 0x04,
  SELF_TEST_X_ACCEL = 0x0E,
  SELF_TEST_Y_ACCEL = 0x0F,
  SELF_TEST_Z_ACCEL = 0x10,
  TIMEBASE_CORRECTION_PLL = 0x28,
};

/// USER BANK 2 (§7.3): rates, ranges, filters.
enum class Reg2 : std::uint8_t {
  GYRO_SMPLRT_DIV = 0x00,
  GYRO_CONFIG_1 = 0x01,
  GYRO_CONFIG_2 = 0x02,
  ODR_ALIGN_EN = 0x09,
  ACCEL_SMPLRT_DIV_1 = 0x10,  // bits [3:0]: divider bits [11:8]
  ACCEL_SMPLRT_DIV_2 = 0x11,  // divider bits [7:0]
  ACCEL_CONFIG = 0x14,
  ACCEL_CONFIG_2 = 0x15,
  TEMP_CONFIG = 0x53,
};

/// USER BANK 3 (§7.4): the auxiliary I2C master (the AK09916 hangs on it).
enum class Reg3 : std::uint8_t {
  I2C_MST_ODR_CONFIG = 0x00,
  I2C_MST_CTRL = 0x01,
  I2C_MST_DELAY_CTRL = 0x02,
  I2C_SLV0_ADDR = 0x03,
  I2C_SLV0_REG = 0x04,
  I2C_SLV0_CTRL = 0x05,
  I2C_SLV0_DO = 0x06,
  I2C_SLV4_ADDR = 0x13,
  I2C_SLV4_REG = 0x14,
  I2C_SLV4_CTRL = 0x15,
  I2C_SLV4_DO = 0x16,
  I2C_SLV4_DI = 0x17,
};

// ---- Bank 0 bits --------------------------------------------------------------------------

/// USER_CTRL (§8.2).
enum USER_CTRL_BIT : std::uint8_t {
  DMP_EN = (1u << 7),       // [7]
  FIFO_EN = (1u << 6),      // [6] FIFO operation
  I2C_MST_EN = (1u << 5),   // [5] auxiliary I2C master
  I2C_IF_DIS = (1u << 4),   // [4] SPI only
  DMP_RST = (1u << 3),      // [3]
  SRAM_RST = (1u << 2),     // [2] FIFO (SRAM) reset
  I2C_MST_RST = (1u << 1),  // [1] I2C master reset
};

/// PWR_MGMT_1 (§8.4).
enum PWR_MGMT_1_BIT : std::uint8_t {
  DEVICE_RESET = (1u << 7),    // [7] reset all registers; self-clearing
  SLEEP = (1u << 6),           // [6]
  LP_EN = (1u << 5),           // [5]
  TEMP_DIS = (1u << 3),        // [3]
  CLKSEL_AUTO = (1u << 0),     // [2:0] = 1: best available clock (PLL when ready)
  CLKSEL_MASK = (0x07u << 0),  // [2:0]
};

/// INT_PIN_CFG (§8.6).
enum INT_PIN_CFG_BIT : std::uint8_t {
  INT1_ACTL = (1u << 7),         // [7] 1: active low
  INT1_OPEN = (1u << 6),         // [6] 1: open drain
  INT1_LATCH_EN = (1u << 5),     // [5] 0: 50 us pulse
  INT_ANYRD_2CLEAR = (1u << 4),  // [4]
  BYPASS_EN = (1u << 1),         // [1] aux bus bridged to the host bus
};

/// INT_ENABLE_1 (§8.8).
enum INT_ENABLE_1_BIT : std::uint8_t {
  RAW_DATA_0_RDY_EN = (1u << 0),  // [0] data-ready on INT1
};

/// INT_STATUS_2 (§8.14): FIFO overflow, one bit per FIFO; cleared on read.
enum INT_STATUS_2_BIT : std::uint8_t {
  FIFO_OVERFLOW_INT = (0x1Fu << 0),  // [4:0]
};

/// I2C_MST_STATUS (§8.12), cleared on read.
enum I2C_MST_STATUS_BIT : std::uint8_t {
  I2C_SLV4_DONE = (1u << 6),  // [6] SLV4 transfer complete
  I2C_SLV4_NACK = (1u << 4),  // [4] SLV4 got a NACK
  I2C_SLV0_NACK = (1u << 0),  // [0]
};

/// FIFO_EN_2 (§8.40): which sensors the FIFO records (in register order: accel, gyro, temp).
enum FIFO_EN_2_BIT : std::uint8_t {
  ACCEL_FIFO_EN = (1u << 4),   // [4]
  GYRO_Z_FIFO_EN = (1u << 3),  // [3]
  GYRO_Y_FIFO_EN = (1u << 2),  // [2]
  GYRO_X_FIFO_EN = (1u << 1),  // [1]
  TEMP_FIFO_EN = (1u << 0),    // [0]
};

/// FIFO_RST (§8.41): assert then de-assert to empty the FIFO.
enum FIFO_RST_BIT : std::uint8_t {
  FIFO_RESET = (0x1Fu << 0),  // [4:0]
};

/// FIFO_MODE (§8.42): 0 stream (overwrite oldest), 1 snapshot (stop when full).
enum FIFO_MODE_BIT : std::uint8_t {
  FIFO_MODE_SNAPSHOT = (0x1Fu << 0),  // [4:0]
};

/// FIFO_COUNTH (§8.43) holds count bits [12:8] in its bits [4:0].
inline constexpr std::uint8_t kFifoCountHMask = 0x1F;

// ---- Bank 2 bits --------------------------------------------------------------------------

/// GYRO_CONFIG_1 (§8.67).
enum GYRO_CONFIG_1_BIT : std::uint8_t {
  GYRO_DLPFCFG_MASK = (0x07u << 3),  // [5:3]
  GYRO_FS_SEL_MASK = (0x03u << 1),   // [2:1] 0 ±250, 1 ±500, 2 ±1000, 3 ±2000 dps
  GYRO_FCHOICE = (1u << 0),          // [0] 1: DLPF on (and the sample rate divider applies)
};
constexpr std::uint8_t gyro_dlpfcfg(std::uint8_t cfg) { return (cfg & 0x07u) << 3; }
constexpr std::uint8_t gyro_fs_sel(std::uint8_t fs) { return (fs & 0x03u) << 1; }

/// GYRO_CONFIG_2 (§8.68): self-test enables.
enum GYRO_CONFIG_2_BIT : std::uint8_t {
  XGYRO_CTEN = (1u << 5),  // [5]
  YGYRO_CTEN = (1u << 4),  // [4]
  ZGYRO_CTEN = (1u << 3),  // [3]
};

/// ACCEL_CONFIG (§8.76).
enum ACCEL_CONFIG_BIT : std::uint8_t {
  ACCEL_DLPFCFG_MASK = (0x07u << 3),  // [5:3]
  ACCEL_FS_SEL_MASK = (0x03u << 1),   // [2:1] 0 ±2, 1 ±4, 2 ±8, 3 ±16 g
  ACCEL_FCHOICE = (1u << 0),          // [0] 1: DLPF on
};
constexpr std::uint8_t accel_dlpfcfg(std::uint8_t cfg) { return (cfg & 0x07u) << 3; }
constexpr std::uint8_t accel_fs_sel(std::uint8_t fs) { return (fs & 0x03u) << 1; }

/// ACCEL_CONFIG_2 (§8.77): self-test enables.
enum ACCEL_CONFIG_2_BIT : std::uint8_t {
  AX_ST_EN_REG = (1u << 4),  // [4]
  AY_ST_EN_REG = (1u << 3),  // [3]
  AZ_ST_EN_REG = (1u << 2),  // [2]
};

// ---- Bank 3 bits --------------------------------------------------------------------------

/// I2C_MST_CTRL (§8.82).
enum I2C_MST_CTRL_BIT : std::uint8_t {
  I2C_MST_P_NSR = (1u << 4),         // [4] stop between reads
  I2C_MST_CLK_MASK = (0x0Fu << 0),   // [3:0]
  I2C_MST_CLK_345_6KHZ = (7u << 0),  // recommended setting (table 23)
};

/// I2C_SLVx_ADDR (§8.84): [7] 1 = read, [6:0] the slave's address.
inline constexpr std::uint8_t kI2cSlvRnw = (1u << 7);

/// I2C_SLVx_CTRL (§8.86).
enum I2C_SLV_CTRL_BIT : std::uint8_t {
  I2C_SLV_EN = (1u << 7),            // [7]
  I2C_SLV_BYTE_SW = (1u << 6),       // [6]
  I2C_SLV_REG_DIS = (1u << 5),       // [5]
  I2C_SLV_GRP = (1u << 4),           // [4]
  I2C_SLV_LENG_MASK = (0x0Fu << 0),  // [3:0] bytes to read
};

// ---- AK09916 (behind the auxiliary I2C master) ----------------------------------------------

namespace ak09916 {
inline constexpr std::uint8_t kAddress = 0x0C;    //!< fixed 7-bit address
inline constexpr std::uint8_t kWia2Value = 0x09;  //!< device ID (§9.3)
inline constexpr double kUtPerLsb = 0.15;         //!< §3.3 sensitivity
inline constexpr std::size_t kBurstLength = 9;    //!< ST1, HXL..HZH, TMPS, ST2

enum class Reg : std::uint8_t {
  WIA1 = 0x00,
  WIA2 = 0x01,
  ST1 = 0x10,
  HXL = 0x11,  // HXL, HXH, HYL, HYH, HZL, HZH: little-endian int16
  ST2 = 0x18,  // reading ST2 releases the data lock: always read through it
  CNTL2 = 0x31,
  CNTL3 = 0x32,
};

enum ST1_BIT : std::uint8_t {
  DRDY = (1u << 0),  // [0] new data
  DOR = (1u << 1),   // [1] data overrun (a sample was skipped)
};
enum ST2_BIT : std::uint8_t {
  HOFL = (1u << 3),  // [3] magnetic sensor overflow: the sample is invalid
};
enum CNTL2_MODE : std::uint8_t {
  POWER_DOWN = 0x00,
  CONTINUOUS_10HZ = 0x02,   // mode 1
  CONTINUOUS_20HZ = 0x04,   // mode 2
  CONTINUOUS_50HZ = 0x06,   // mode 3
  CONTINUOUS_100HZ = 0x08,  // mode 4
};
enum CNTL3_BIT : std::uint8_t { SRST = (1u << 0) };
}  // namespace ak09916

// ---- FIFO record ----------------------------------------------------------------------------

/// One FIFO record with FIFO_EN_2 = ACCEL | GYRO_X | GYRO_Y | GYRO_Z (no temperature, no
/// external sensor): the sensors' output registers in register order, big-endian (§4.19).
struct FifoRecord {
  std::uint8_t ACCEL_XOUT_H, ACCEL_XOUT_L;
  std::uint8_t ACCEL_YOUT_H, ACCEL_YOUT_L;
  std::uint8_t ACCEL_ZOUT_H, ACCEL_ZOUT_L;
  std::uint8_t GYRO_XOUT_H, GYRO_XOUT_L;
  std::uint8_t GYRO_YOUT_H, GYRO_YOUT_L;
  std::uint8_t GYRO_ZOUT_H, GYRO_ZOUT_L;
};
static_assert(sizeof(FifoRecord) == 12, "FIFO record: accel 6 + gyro 6 bytes, no padding");
inline constexpr std::size_t kFifoMaxRecords = kFifoSize / sizeof(FifoRecord);  // 42

}  // namespace wallar::drivers::icm20948
