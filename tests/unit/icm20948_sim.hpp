// SPDX-License-Identifier: Apache-2.0
/// @file icm20948_sim.hpp
/// @brief A register-level ICM-20948 (+ AK09916 behind its aux master) on the I2cAdapter seam:
/// it receives the i2c_rdwr_ioctl_data the kernel would and answers from its register file.
///
/// What it models: 4 user banks and REG_BANK_SEL; DEVICE_RESET (registers to their reset
/// values, bank 0, sleep); sampling at 1125 Hz / (1 + GYRO_SMPLRT_DIV) from wake-up, on its
/// own (optionally wrong) oscillator; the FIFO (512 bytes, the enabled sensors in register
/// order, big-endian, snapshot or stream mode, INT_STATUS_2 overflow bits, FIFO_COUNT,
/// FIFO_R_W popping bytes, 0xFF and nothing popped when empty, FIFO_RST); register bursts
/// auto-increment but stop at FIFO_R_W; a data-ready edge per sample when INT_ENABLE_1 asks;
/// clear-on-read status registers; the aux master's SLV4 one-shot transfers and SLV0 periodic
/// reads of an AK09916 that measures at 100 Hz in its own axes (Y, Z opposite to the accel's).
/// Motion comes from a truth function; every generated sample is logged with its raw values.
/// Faults: NACK, EIO, short reads, a stuck bus, unplugging, NACKs after reset.
///
/// Threading: test-thread only.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <vector>

#include "wallar/core/time.hpp"
#include "wallar/drivers/bus/i2c.hpp"

namespace wallar::test {

/// What the chip senses at sample k, time t (body frame = the chip's accel/gyro frame).
struct SimTruth {
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.80665);
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d mag_body_uT = Eigen::Vector3d(20.0, -5.0, -40.0);
  double temperature_c = 30.0;
};
using SimTruthFn = std::function<SimTruth(std::uint64_t k, TimeNs t_ns)>;

/// One sample the chip made.
struct SimSample {
  std::uint64_t k = 0;                  //!< running index since power-up
  TimeNs t_ns = 0;                      //!< when it was sampled (the data-ready edge)
  std::array<std::int16_t, 3> accel{};  //!< raw LSB, chip frame
  std::array<std::int16_t, 3> gyro{};
  bool to_fifo = false;       //!< the FIFO was recording
  bool lost_on_chip = false;  //!< the FIFO was full (overflow)
};

/// One transfer on the bus, as the device saw it.
struct SimTraffic {
  std::uint16_t addr = 0;
  std::uint8_t bank = 0;
  std::uint8_t reg = 0;
  std::uint16_t write_len = 0;  //!< bytes written including the register pointer
  std::uint16_t read_len = 0;
  int result = 0;  //!< what rdwr returned
};

class Icm20948Sim final : public drivers::I2cAdapter {
 public:
  /// kEio fails before any byte moves; kShortRead completes half a read and says so;
  /// kEioMidRead waits for the next read that reaches FIFO_R_W, clocks half of it out (FIFO
  /// bytes leave the chip) and then fails with EIO, as a bus error part-way through a burst
  /// does.
  enum class Fault : std::uint8_t { kNack, kEio, kShortRead, kEioMidRead };

  explicit Icm20948Sim(std::uint16_t address = 0x68, SimTruthFn truth = {});

  int rdwr(i2c_rdwr_ioctl_data& data) override;
  [[nodiscard]] std::size_t max_read_bytes() const override { return max_read_bytes_; }
  /// Reads longer than `bytes` fail with EOPNOTSUPP, as on an SMBus-only adapter.
  void set_max_read_bytes(std::size_t bytes) { max_read_bytes_ = bytes; }

  /// Moves the simulated time to t_ns, making every sample due by then.
  void advance_to(TimeNs t_ns);
  [[nodiscard]] TimeNs now() const { return now_ns_; }
  /// Time of the next sample (and data-ready edge when enabled), or nullopt while asleep.
  [[nodiscard]] std::optional<TimeNs> next_sample_time() const;
  [[nodiscard]] bool data_ready_enabled() const;

  // ---- Faults --------------------------------------------------------------------------
  /// The next `count` transfers to the device fail with `fault`.
  void inject(Fault fault, int count = 1);
  /// Every transfer fails with ETIMEDOUT (SDA held low) while set.
  void set_stuck(bool stuck) { stuck_ = stuck; }
  /// Every transfer NACKs (ENXIO) while set; plugging back in powers the chip up afresh.
  void set_unplugged(bool unplugged);
  /// After each DEVICE_RESET the next `count` transfers NACK (the chip is booting).
  void set_nack_after_reset(int count) { nack_after_reset_ = count; }
  /// The magnetometer does not answer on the aux bus.
  void set_mag_present(bool present) { mag_present_ = present; }
  /// Self-test response relative to the factory trim (1 = a healthy chip, 0 = dead MEMS).
  void set_self_test_gain(double g) { self_test_gain_ = g; }
  /// Oscillator error as a fraction (0.01 = 1 % slow).
  void set_rate_error(double e) { rate_error_ = e; }
  /// Writes a register behind the driver's back.
  void poke(int bank, std::uint8_t reg, std::uint8_t value) { regs_[bank][reg] = value; }
  [[nodiscard]] std::uint8_t peek(int bank, std::uint8_t reg) const { return regs_[bank][reg]; }

  // ---- What happened -------------------------------------------------------------------
  [[nodiscard]] const std::vector<SimSample>& samples() const { return samples_; }
  /// Samples that went into (or overflowed) the FIFO with t in (t0, t1].
  [[nodiscard]] std::uint64_t fifo_samples_between(TimeNs t0, TimeNs t1) const;
  [[nodiscard]] const std::vector<SimTraffic>& traffic() const { return traffic_; }
  void set_logging(bool on) { logging_ = on; }
  void clear_traffic() { traffic_.clear(); }
  [[nodiscard]] int device_resets() const { return device_resets_; }
  [[nodiscard]] std::size_t fifo_bytes() const { return fifo_size_; }
  /// Raw AK09916 field of the latest measurement (AK axes) and the number of measurements.
  [[nodiscard]] std::array<std::int16_t, 3> mag_raw() const { return mag_raw_; }
  [[nodiscard]] int mag_measurements() const { return mag_measurements_; }
  /// Every AK09916 measurement, raw, AK axes.
  [[nodiscard]] const std::vector<std::array<std::int16_t, 3>>& mag_log() const { return mag_log_; }
  /// Reserves room for n samples so that a test can count the driver's allocations alone.
  void reserve(std::size_t n) {
    samples_.reserve(n);
    mag_log_.reserve(n / 8);
  }

 private:
  void power_on_reset();
  void write_reg(std::uint8_t reg, std::uint8_t value);
  std::uint8_t read_reg(std::uint8_t reg);
  void make_sample(TimeNs t_ns);
  void fifo_push(std::uint8_t b);
  std::uint8_t fifo_pop();
  void slv4_transfer();
  void aux_read();
  [[nodiscard]] bool awake() const;
  [[nodiscard]] DurationNs period_ns() const;
  int bank() const { return (regs_[0][0x7F] >> 4) & 0x03; }

  std::uint16_t address_;
  SimTruthFn truth_;
  std::array<std::array<std::uint8_t, 128>, 4> regs_{};
  std::array<std::uint8_t, 0x40> ak_{};   // AK09916 registers
  std::array<std::uint8_t, 512> fifo_{};  // ring: no allocation while streaming
  std::size_t fifo_head_ = 0;
  std::size_t fifo_size_ = 0;
  TimeNs now_ns_ = 0;
  TimeNs next_sample_ns_ = 0;
  bool was_awake_ = false;
  std::uint64_t k_ = 0;
  TimeNs next_mag_ns_ = 0;
  TimeNs last_aux_ns_ = 0;
  std::array<std::int16_t, 3> mag_raw_{};
  int mag_measurements_ = 0;
  std::vector<std::array<std::int16_t, 3>> mag_log_;
  std::vector<SimSample> samples_;
  std::vector<SimTraffic> traffic_;
  std::size_t max_read_bytes_ = drivers::kI2cNoReadLimit;
  bool logging_ = true;
  std::deque<Fault> faults_;
  bool stuck_ = false;
  bool unplugged_ = false;
  int nack_after_reset_ = 0;
  int nack_budget_ = 0;
  bool mag_present_ = true;
  double rate_error_ = 0.0;
  double self_test_gain_ = 1.0;
  int device_resets_ = 0;
};

}  // namespace wallar::test
