// SPDX-License-Identifier: Apache-2.0
/// @file icm20948.hpp
/// @brief InvenSense ICM-20948 (accel + gyro + AK09916 magnetometer) over I2C: a non-blocking
/// PX4-style state machine streaming the FIFO, stamped at the data-ready edges.
///
/// State machine (ImuDriver::step):
///   RESET          write PWR_MGMT_1.DEVICE_RESET.
///   WAIT_FOR_RESET probe WHO_AM_I (0xEA) and PWR_MGMT_1 back at its reset value, retried every
///                  millisecond, back to RESET after 100 ms.
///   CONFIGURE      write the configuration table {bank, reg, set_bits, clear_bits}
///                  (read-modify-write), read every entry back; then, with the magnetometer,
///                  probe the AK09916 (WIA2 = 0x09) and set it to 100 Hz continuous through the
///                  auxiliary master's one-shot slave 4; then empty the FIFO.
///   RUN            on data-ready edges (every `fifo_read_every`-th) or on the timeout: one
///                  burst from FIFO_COUNTH reads the count and the records the edges
///                  announced (the address stops at FIFO_R_W); more records than edges, or
///                  polling, read the rest (or all) from FIFO_R_W, in transfers of whole
///                  records where the bus carries less (an SMBus-only adapter's 32 bytes:
///                  max_read_bytes()); push them; read the magnetometer's copy in
///                  EXT_SLV_SENS_DATA every 5 ms; re-check one configuration register every
///                  10 ms (a mismatch counts config_mismatch and resets). A count with no
///                  room for another record is an overflow (snapshot mode stopped the FIFO).
///                  A burst that fails part-way, or that read past the FIFO's records, is
///                  never repeated: the FIFO is emptied and started over (resync).
/// Every failed transfer counts in its class (nack, short_transfer, bad_transfer) and raises a
/// failure counter that good transfers lower; past `failure_limit` the device is reset. Every
/// return to RESET after the first counts in `resets`. Nothing sleeps.
///
/// Timestamps: the data-ready edge's kernel timestamp is the sample time of the record that
/// raised it (edges and records are paired in order); DeviceClock maps record indices to
/// monotonic time, so records read in a batch are back-dated by the period. Without edges
/// (the line stopped, or none is wired) the read time now_ns is the observation (an upper
/// bound, absorbed slowly by DeviceClock). publish_t_ns = now_ns.
///
/// Frames: the body frame is the chip's accel/gyro frame (DS-000189 §12, figure 16). The
/// AK09916 die is mounted with its Y and Z axes opposite (same figure: "magnetometer axes"),
/// so mag_body = (mx, -my, -mz).
///
/// Threading: one thread (the imu thread) owns the driver and its I2cDevice; step() is not
/// re-entrant and calls the sink on that thread. No allocation after construction.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string_view>

#include "wallar/drivers/bus/i2c.hpp"
#include "wallar/drivers/imu/device_clock.hpp"
#include "wallar/drivers/imu/icm20948_registers.hpp"
#include "wallar/drivers/imu/imu_driver.hpp"

namespace wallar::drivers {

// ---- Byte reassembly and scaling (pure, unit-tested against hand-computed vectors) ---------
namespace icm20948 {

inline constexpr double kStandardGravity = 9.80665;  //!< [m/s^2 per g]

/// ACCEL_FS_SEL values (§8.76).
enum class AccelRange : std::uint8_t { k2g = 0, k4g = 1, k8g = 2, k16g = 3 };
/// GYRO_FS_SEL values (§8.67).
enum class GyroRange : std::uint8_t { k250dps = 0, k500dps = 1, k1000dps = 2, k2000dps = 3 };

constexpr std::int16_t be16(std::uint8_t hi, std::uint8_t lo) {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>((hi << 8) | lo));
}
constexpr std::int16_t le16(std::uint8_t lo, std::uint8_t hi) { return be16(hi, lo); }

/// §3.2 table 2: 16384 LSB/g at ±2 g, halving per range step (2048 at ±16 g).
constexpr double accel_lsb_per_g(AccelRange r) {
  return 16384.0 / static_cast<double>(1u << static_cast<unsigned>(r));
}
/// §3.1 table 1: 131 LSB/dps at ±250 dps, halving per range step (16.4 at ±2000 dps).
constexpr double gyro_lsb_per_dps(GyroRange r) {
  constexpr std::array<double, 4> kLsb{131.0, 65.5, 32.8, 16.4};
  return kLsb[static_cast<unsigned>(r)];
}
/// §8.23 TEMP_OUT: degC = (TEMP_OUT - RoomTemp_Offset) / Temp_Sensitivity + 21,
/// offset 21 LSB, sensitivity 333.87 LSB/degC (§3.4 table 4).
constexpr double temperature_c(std::int16_t temp_out) {
  return (static_cast<double>(temp_out) - 21.0) / 333.87 + 21.0;
}

struct ScaledRecord {
  Eigen::Vector3d accel_m_s2;
  Eigen::Vector3d gyro_rad_s;
};
/// One FIFO record in SI units, body frame (= chip frame).
ScaledRecord scale_record(const FifoRecord& r, AccelRange ar, GyroRange gr);

/// The 9-byte AK09916 burst ST1, HXL..HZH, TMPS, ST2: the field in the BODY frame [uT] when it
/// is a new, valid measurement (ST1.DRDY set, ST2.HOFL clear), else nullopt.
std::optional<Eigen::Vector3d> ak09916_body_uT(std::span<const std::uint8_t, 9> burst);

/// Sample-rate divider for the requested rate: ODR = 1125 Hz / (1 + div) (§8.66, §8.74),
/// the nearest achievable rate, div in [0, 255].
std::uint8_t rate_divider(double rate_hz);
constexpr double rate_of_divider(std::uint8_t div) { return kBaseRateHz / (1.0 + div); }

/// Self-test evaluation (simplified, after InvenSense's MPU-9250/ICM-20948 self-test note):
/// the factory response is ST_OTP = 2620 * 1.01^(code - 1) LSB at the ±250 dps / ±2 g ranges
/// (code 0 = no trim stored: fail); the measured response is the mean output with self-test
/// on minus the mean with it off, at those ranges. An axis passes when response / ST_OTP is
/// within [0.5, 1.5]. (The full procedure also bounds the absolute response when no trim is
/// stored and checks the gyro offset; we do not.)
struct SelfTestResult {
  std::array<double, 3> gyro_ratio{};   //!< response / factory response, x y z
  std::array<double, 3> accel_ratio{};  //!< same for the accelerometer
  bool gyro_pass = false;
  bool accel_pass = false;
  [[nodiscard]] bool pass() const { return gyro_pass && accel_pass; }
};
double self_test_factory_response(std::uint8_t otp_code);
SelfTestResult evaluate_self_test(const std::array<double, 3>& gyro_off_lsb,
                                  const std::array<double, 3>& gyro_on_lsb,
                                  const std::array<std::uint8_t, 3>& gyro_otp,
                                  const std::array<double, 3>& accel_off_lsb,
                                  const std::array<double, 3>& accel_on_lsb,
                                  const std::array<std::uint8_t, 3>& accel_otp);

/// Runs the self-test on the chip: wakes it at ±250 dps / ±2 g, averages `samples` reads of
/// the output registers with self-test off and then on (after `settle_ns`), reads the factory
/// codes from bank 1 SELF_TEST_*, and evaluates. `wait(ns)` is how the caller lets time pass
/// (a sleep on the board, advancing the simulator in tests): this is a start-up or
/// maintenance procedure, not part of the non-blocking streaming path. It leaves the chip
/// reconfigured: run it before the driver starts, or let the driver's configuration re-check
/// reset it. Returns nullopt when a transfer fails.
std::optional<SelfTestResult> run_self_test(I2cDevice& device,
                                            const std::function<void(DurationNs)>& wait,
                                            int samples = 50, DurationNs settle_ns = 20 * kNsPerMs);

}  // namespace icm20948

/// The driver.
class Icm20948 final : public ImuDriver {
 public:
  struct Config {
    double rate_hz = 1000.0;  //!< requested ODR; the chip gives 1125/(1+div) [Hz]
    icm20948::AccelRange accel_range = icm20948::AccelRange::k16g;
    icm20948::GyroRange gyro_range = icm20948::GyroRange::k2000dps;
    bool mag_enabled = true;
    bool has_data_ready = true;    //!< an interrupt line feeds step() its edges
    unsigned fifo_read_every = 1;  //!< edges per FIFO read (the watermark, 1..kFifoMaxRecords/2)
    int failure_limit = 10;        //!< failure counter above this: full reset
  };

  /// Nothing is sent until the first step().
  Icm20948(I2cDevice& device, const Config& config, ImuSampleSink& sink);

  TimeNs step(TimeNs now_ns, std::optional<TimeNs> data_ready_ns) override;
  [[nodiscard]] ImuDriverState state() const override { return state_; }
  [[nodiscard]] const ImuCounters& counters() const override { return counters_; }
  [[nodiscard]] std::string_view name() const override { return "icm20948"; }

  /// The configured output data rate [Hz] and period [ns].
  [[nodiscard]] double rate_hz() const { return rate_hz_; }
  [[nodiscard]] DurationNs period_ns() const { return period_ns_; }
  /// True while data-ready edges are overdue and the driver reads the FIFO on its own timer.
  [[nodiscard]] bool polling() const { return polling_; }
  /// True when the AK09916 answered and streams (false: mag disabled or absent).
  [[nodiscard]] bool mag_ok() const { return mag_ok_; }
  /// Times the magnetometer was found missing or wrong (WIA2) during CONFIGURE.
  [[nodiscard]] std::uint64_t mag_probe_failures() const { return mag_probe_failures_; }

 private:
  struct ConfigEntry {
    icm20948::Bank bank;
    std::uint8_t reg;
    std::uint8_t set_bits;
    std::uint8_t clear_bits;
  };
  enum class ConfigPhase : std::uint8_t {
    kTable,
    kMagProbe,
    kMagProbeCheck,
    kMagMode,
    kMagModeCheck,
    kFifoStart
  };

  TimeNs step_reset(TimeNs now_ns);
  TimeNs step_wait_for_reset(TimeNs now_ns);
  TimeNs step_configure(TimeNs now_ns);
  TimeNs step_run(TimeNs now_ns, std::optional<TimeNs> data_ready_ns);
  TimeNs read_fifo(TimeNs now_ns, bool edge);
  void flush_fifo(TimeNs now_ns, bool edge, bool overflow);
  void enter_reset(TimeNs now_ns);
  bool check_failures(TimeNs now_ns);

  bool select_bank(icm20948::Bank bank);
  /// repeatable = false for a register whose read changes the chip (FIFO_R_W, the
  /// clear-on-read INT_STATUS_*): attempted once, never retried by the bus.
  bool read(icm20948::Bank bank, std::uint8_t reg, std::span<std::uint8_t> out,
            bool repeatable = true);
  bool write(icm20948::Bank bank, std::uint8_t reg, std::uint8_t value);
  bool transfer(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx,
                bool repeatable = true);
  bool write_entry(const ConfigEntry& e);
  bool entry_ok(const ConfigEntry& e, bool& ok);
  bool slv4(std::uint8_t addr, std::uint8_t reg, std::uint8_t dout);

  I2cDevice& device_;
  Config config_;
  ImuSampleSink& sink_;
  std::uint8_t divider_;
  double rate_hz_;
  DurationNs period_ns_;

  ImuDriverState state_ = ImuDriverState::kReset;
  ImuCounters counters_;
  DeviceClock clock_;
  bool first_reset_ = true;
  int failures_ = 0;
  int bank_ = -1;  // cached REG_BANK_SEL, -1 unknown

  std::array<ConfigEntry, 20> table_{};
  std::size_t table_size_ = 0;
  std::size_t recheck_ = 0;
  ConfigPhase phase_ = ConfigPhase::kTable;
  int configure_attempts_ = 0;
  TimeNs t_state_ns_ = 0;

  bool mag_ok_ = false;
  std::uint64_t mag_probe_failures_ = 0;
  std::array<std::uint8_t, 9> last_mag_burst_{};
  TimeNs t_mag_read_ns_ = 0;

  // RUN bookkeeping.
  std::uint64_t k_next_ = 0;       // index of the next record to be read
  std::uint64_t k_edge_next_ = 0;  // index of the record the next edge belongs to
  unsigned pending_edges_ = 0;     // edges since the last read
  TimeNs t_last_edge_ns_ = 0;
  TimeNs t_last_wake_edge_ns_ = 0;  // newest edge, for the overdue check
  bool polling_ = false;
  bool have_last_sample_ = false;
  TimeNs t_last_sample_ns_ = 0;

  TimeNs t_recheck_ns_ = 0;
  int last_error_ = 0;  // of the latest transfer (0, an errno, kI2cShortTransfer)

  // FIFO_COUNTH, FIFO_COUNTL, then up to a full FIFO of records.
  static constexpr std::size_t kFifoCountBytes = 2;
  std::array<std::uint8_t, kFifoCountBytes + icm20948::kFifoSize> fifo_buf_{};
};

}  // namespace wallar::drivers
