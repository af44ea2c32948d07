// SPDX-License-Identifier: Apache-2.0
/// @file bno055_uart.hpp
/// @brief Bosch BNO055 over its UART interface: a non-blocking RESET -> WAIT_FOR_RESET ->
/// CONFIGURE -> RUN state machine that polls the fused outputs at a fixed rate.
///
/// Every transaction is one request and one response (bno055_protocol.hpp). step() writes a
/// request and returns; a later step() reads whatever bytes arrived (the caller polls fd()
/// for POLLIN or sleeps until the time step() returned). Nothing sleeps, nothing blocks
/// longer than a write into the kernel's tty buffer.
///
///  - RESET: PAGE_ID := 0, then SYS_TRIGGER := RST_SYS (bit 5); the ack, if the chip sends one
///    before it resets, is discarded.
///  - WAIT_FOR_RESET: read CHIP_ID every probe_interval until it reads 0xA0 (the chip boots
///    in ~650 ms and does not answer meanwhile); a wrong id or no answer by reset_timeout
///    counts a probe failure and resets again.
///  - CONFIGURE: OPR_MODE := CONFIG, then each entry of the config table {reg, set, clear}
///    (UNIT_SEL, PWR_MODE, OPR_MODE := NDOF last) read, written, and read back.
///  - RUN: at rate_hz, one burst read of ACC_DATA_X_LSB..TEMP (0x08..0x34, 45 bytes); after
///    every kRecheckEvery samples one config entry is read back round-robin; a mismatch
///    counts config_mismatch and resets the chip.
///
/// Failures: every failed transaction counts bad_transfer (and nack for an 0xEE error
/// status, resync for a frame with a wrong length, short_transfer for a frame cut off by the
/// timeout) and raises a failure counter that good transactions lower; past max_failures
/// the chip is fully reset (resets). 0xEE 0x07 BUS_OVER_RUN_ERROR, the chip's known answer
/// under load, is retried at once up to max_overrun_retries times (uart_counters()).
/// Every poll tick that yields no sample counts one dropped_samples: no sample is invented.
///
/// Clock model (the sample's t_ns): the chip latches its output registers when it processes
/// the read request, then sends 2 + 45 bytes. So
///     t_obs = t_rx - (2 + 45) * 10 bits / baud,   t_sample = t_obs - processing_latency
/// where t_rx is the now_ns of the step() that found the response complete (an upper bound:
/// the caller wakes on POLLIN) and processing_latency (kBno055ProcessingLatencyNs) is the
/// chip's assumed time from the last request byte to the first response byte. Observations
/// go through DeviceClock (index = poll tick, period = 1 / rate_hz, fixed latency =
/// processing_latency) which keeps the lower envelope, so a late wake-up does not move the
/// stamp. Not modelled: the fused output's own age (it updates at 100 Hz, so it is 0..10 ms
/// old when latched); camera-IMU time offset calibration absorbs its mean.
/// publish_t_ns is the now_ns of the step() that pushed the sample.
///
/// Threading: ImuDriver's contract: one thread owns the driver and its serial port.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "wallar/drivers/imu/bno055_protocol.hpp"
#include "wallar/drivers/imu/device_clock.hpp"
#include "wallar/drivers/imu/imu_driver.hpp"
#include "wallar/drivers/serial/serial_port.hpp"

namespace wallar::drivers {

/// Assumed time the BNO055 takes from receiving a read request to sending the first byte of
/// its response (register copy in the chip's MCU). Not in the datasheet: a documented
/// assumption to be measured on hardware (scope on TX/RX); its error becomes a constant
/// time offset that camera-IMU calibration absorbs.
inline constexpr DurationNs kBno055ProcessingLatencyNs = 500'000;

struct Bno055UartConfig {
  std::string device;       //!< e.g. /dev/ttyUSB0 (USB-UART bridge) or /dev/serial0
  int baud = 115200;        //!< the chip's UART runs at 115200 8N1
  double rate_hz = 100.0;   //!< poll rate, (0, 100]: the fusion output updates at 100 Hz
  bool gyro_in_rps = true;  //!< UNIT_SEL GYR_Unit: rad/s (900 LSB) instead of dps (16 LSB)
  DurationNs response_timeout_ns = 20 * kNsPerMs;  //!< per transaction, after the request
  DurationNs reset_timeout_ns = 1500 * kNsPerMs;   //!< CHIP_ID must read 0xA0 by then
  DurationNs probe_interval_ns = 50 * kNsPerMs;    //!< CHIP_ID poll period while booting
  DurationNs retry_backoff_ns = 100 * kNsPerMs;    //!< wait before a reset after a failure
  int max_failures = 10;                           //!< failure counter limit before a full reset
  int max_overrun_retries = 3;                     //!< immediate retries of a BUS_OVER_RUN read
  DurationNs processing_latency_ns = kBno055ProcessingLatencyNs;
};

/// UART-level detail beyond ImuCounters.
struct Bno055UartCounters {
  std::uint64_t requests = 0;         //!< requests written completely
  std::uint64_t responses = 0;        //!< well-formed responses parsed
  std::uint64_t timeouts = 0;         //!< transactions with no complete answer in time
  std::uint64_t overrun_retries = 0;  //!< reads retried after BUS_OVER_RUN_ERROR
  std::uint64_t garbage_bytes = 0;    //!< bytes dropped before a start byte
  std::uint64_t partial_reads = 0;    //!< responses that arrived over more than one read()
  std::uint64_t io_errors = 0;        //!< read()/write() failures other than timeouts
  std::uint64_t reopen_failures = 0;  //!< the device node could not be reopened
  /// 0xEE responses by status code (index = code, 1..10).
  std::array<std::uint64_t, bno055::kMaxStatusCode + 1> status{};
};

class Bno055Uart final : public ImuDriver {
 public:
  /// Opens the serial port (throws SerialError / InputError like SerialPort) and validates
  /// the configuration (InputError naming the field). The sink must outlive the driver.
  Bno055Uart(Bno055UartConfig config, ImuSampleSink& sink);

  TimeNs step(TimeNs now_ns, std::optional<TimeNs> data_ready_ns) override;
  [[nodiscard]] ImuDriverState state() const override { return state_; }
  [[nodiscard]] const ImuCounters& counters() const override { return counters_; }
  [[nodiscard]] std::string_view name() const override { return "bno055-uart"; }

  [[nodiscard]] const Bno055UartCounters& uart_counters() const { return uart_; }
  /// The serial descriptor to poll for POLLIN (-1 while the device is closed).
  [[nodiscard]] int fd() const { return port_ ? port_->fd() : -1; }
  /// True while a request is out and its response neither complete nor timed out.
  [[nodiscard]] bool awaiting_response() const { return pending_.kind != TxnKind::kNone; }
  /// Re-checks of config entries done since the last reset (diagnostics and tests).
  [[nodiscard]] std::uint64_t config_rechecks() const { return rechecks_; }

  /// One entry of the configuration: after the write, (value & (set | clear)) == set.
  struct ConfigEntry {
    bno055::Reg reg;
    std::uint8_t set;
    std::uint8_t clear;
    DurationNs settle_ns;  //!< wait after writing before the next transaction
  };
  static constexpr std::size_t kConfigEntries = 3;
  /// Samples between two config re-checks in RUN.
  static constexpr std::uint64_t kRecheckEvery = 10;

 private:
  enum class TxnKind : std::uint8_t { kNone, kRead, kWrite };
  enum class TxnResult : std::uint8_t {
    kPending,
    kData,
    kAck,
    kErrorStatus,
    kBadFrame,
    kTimeout,
    kIoError
  };
  struct Pending {
    TxnKind kind = TxnKind::kNone;
    std::uint8_t len = 0;  // bytes asked for (reads)
    TimeNs deadline_ns = 0;
    std::uint32_t reads = 0;  // read() calls that brought bytes for this response
  };
  enum class Phase : std::uint8_t {
    // RESET
    kResetPage,
    kResetTrigger,
    // CONFIGURE
    kConfigMode,
    kEntryRead,
    kEntryWrite,
    kEntryVerify,
    // RUN
    kRunIdle,
    kRunSample,
    kRunCheck,
  };

  void enter_reset(TimeNs now_ns, TimeNs not_before_ns);
  void enter_run(TimeNs now_ns);
  TimeNs step_reset(TimeNs now_ns);
  TimeNs step_wait_for_reset(TimeNs now_ns);
  TimeNs step_configure(TimeNs now_ns);
  TimeNs step_run(TimeNs now_ns);

  bool send_read(bno055::Reg reg, std::size_t len, TimeNs now_ns);
  bool send_write(bno055::Reg reg, std::uint8_t value, TimeNs now_ns);
  bool send(std::span<const std::uint8_t> request);
  TxnResult poll_response(TimeNs now_ns);
  /// Counts a failed transaction; true when the failure limit forced a reset.
  bool fail(TxnResult r, TimeNs now_ns);
  void succeed();
  bool try_reopen();
  void push_sample(TimeNs now_ns);

  Bno055UartConfig config_;
  ImuSampleSink& sink_;
  std::optional<SerialPort> port_;
  std::array<ConfigEntry, kConfigEntries> config_table_{};
  DurationNs period_ns_;
  DeviceClock clock_;

  ImuDriverState state_ = ImuDriverState::kReset;
  Phase phase_ = Phase::kResetPage;
  ImuCounters counters_;
  Bno055UartCounters uart_;
  bool first_reset_ = true;
  int failures_ = 0;
  int overrun_retries_left_ = 0;
  TimeNs not_before_ns_ = 0;  // nothing is sent before this (settling, backoff)
  TimeNs reset_deadline_ns_ = 0;
  std::size_t entry_ = 0;  // config table index (CONFIGURE) / next re-check (RUN)
  std::uint8_t entry_value_ = 0;
  TimeNs next_tick_ns_ = 0;
  std::uint64_t tick_ = 0;         // poll tick index since RUN began: DeviceClock's k
  std::uint64_t sample_tick_ = 0;  // tick of the outstanding burst read
  std::uint64_t samples_since_check_ = 0;
  std::uint64_t rechecks_ = 0;
  TimeNs last_t_ns_ = 0;  // last t_ns pushed: stamps only increase, across resets too

  Pending pending_;
  bno055::UartStatus last_status_ = bno055::UartStatus::kWriteSuccess;
  bno055::RxRing rx_;
  std::array<std::uint8_t, bno055::kMaxLength> data_{};
  std::array<std::uint8_t, 8> tx_{};
};

}  // namespace wallar::drivers
