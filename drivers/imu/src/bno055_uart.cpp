// SPDX-License-Identifier: Apache-2.0
/// @file bno055_uart.cpp
/// @brief The BNO055 UART state machine: one request/response transaction at a time.
#include "wallar/drivers/imu/bno055_uart.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <exception>
#include <utility>

#include "wallar/core/error.hpp"

namespace wallar::drivers {
namespace {

using bno055::Reg;
using bno055::UartStatus;

// Bytes of a read response around its data: 0xBB len.
constexpr std::size_t kReadResponseOverhead = 2;
// Bytes of a status response: 0xEE status.
constexpr std::size_t kStatusResponseBytes = 2;
// A write into the kernel's tty buffer of a few bytes never waits in practice; this bounds
// it if the line is stuck (a hung USB-UART bridge).
constexpr DurationNs kWriteTimeoutNs = 2 * kNsPerMs;

// The device node is gone (USB-UART unplugged, pty master closed): reopen in RESET.
bool device_gone(int err) {
  return err == EIO || err == ENXIO || err == ENODEV || err == EBADF || err == EPIPE;
}

DurationNs period_from_rate(const Bno055UartConfig& c) {
  if (!(c.rate_hz > 0.0 && c.rate_hz <= bno055::kFusionRateHz)) {
    throw_input_error(printable(c.device, 200), 0,
                      "bno055 rate_hz " + std::to_string(c.rate_hz) +
                          " outside (0, 100]: the fusion output updates at 100 Hz");
  }
  if (c.max_failures < 1 || c.max_overrun_retries < 0 || c.response_timeout_ns <= 0 ||
      c.reset_timeout_ns <= 0 || c.probe_interval_ns <= 0 || c.retry_backoff_ns < 0 ||
      c.processing_latency_ns < 0) {
    throw_input_error(printable(c.device, 200), 0, "bno055 timeouts and limits must be positive");
  }
  return static_cast<DurationNs>(std::llround(1e9 / c.rate_hz));
}

}  // namespace

Bno055Uart::Bno055Uart(Bno055UartConfig config, ImuSampleSink& sink)
    : config_(std::move(config)),
      sink_(sink),
      period_ns_(period_from_rate(config_)),
      clock_(period_ns_, 0.05, config_.processing_latency_ns) {
  using namespace bno055;
  const std::uint8_t units = config_.gyro_in_rps ? unit_sel::kGyrRps : std::uint8_t{0};
  config_table_ = {{
      // m/s^2, rad/s (or dps), deg C, Windows orientation convention; reserved bits kept.
      {Reg::kUnitSel, units, static_cast<std::uint8_t>(unit_sel::kDefinedMask & ~units), 0},
      {Reg::kPwrMode, static_cast<std::uint8_t>(PwrMode::kNormal), kPwrModeMask, 0},
      // Last: leaving CONFIG starts the fusion; 7 ms switching time, then the first output.
      {Reg::kOprMode, static_cast<std::uint8_t>(OprMode::kNdof), kOprModeMask,
       kConfigToAnyNs + 13 * kNsPerMs},
  }};
  port_.emplace(config_.device, config_.baud);
  enter_reset(0, 0);
}

TimeNs Bno055Uart::step(TimeNs now_ns, std::optional<TimeNs> /*data_ready_ns*/) {
  switch (state_) {
    case ImuDriverState::kReset:
      return step_reset(now_ns);
    case ImuDriverState::kWaitForReset:
      return step_wait_for_reset(now_ns);
    case ImuDriverState::kConfigure:
      return step_configure(now_ns);
    case ImuDriverState::kRun:
      return step_run(now_ns);
  }
  return now_ns;
}

void Bno055Uart::enter_reset(TimeNs /*now_ns*/, TimeNs not_before_ns) {
  if (!first_reset_) ++counters_.resets;
  first_reset_ = false;
  state_ = ImuDriverState::kReset;
  phase_ = Phase::kResetPage;
  pending_ = {};
  failures_ = 0;
  not_before_ns_ = not_before_ns;
  clock_.reset();
}

void Bno055Uart::enter_run(TimeNs now_ns) {
  state_ = ImuDriverState::kRun;
  phase_ = Phase::kRunIdle;
  entry_ = 0;
  failures_ = 0;
  tick_ = 0;
  samples_since_check_ = 0;
  next_tick_ns_ = now_ns;
  clock_.reset();
}

bool Bno055Uart::try_reopen() {
  try {
    port_.emplace(config_.device, config_.baud);
    return true;
  } catch (const std::exception&) {
    ++uart_.reopen_failures;
    return false;
  }
}

bool Bno055Uart::send(std::span<const std::uint8_t> request) {
  if (!port_) return false;
  // Whatever is still in the line belongs to an abandoned transaction (a late answer, the
  // ack of a reset): it must not be taken for this request's answer.
  uart_.garbage_bytes += rx_.drop_all();
  std::array<std::uint8_t, 64> stale{};
  for (int i = 0; i < 16; ++i) {
    const SerialIo io = port_->read_some(stale, 0);
    if (io.bytes == 0) break;
    uart_.garbage_bytes += io.bytes;
  }
  const SerialIo io = port_->write_all(request, kWriteTimeoutNs);
  if (!io.ok()) {
    ++uart_.io_errors;
    if (device_gone(io.error)) port_.reset();
    return false;
  }
  ++uart_.requests;
  return true;
}

bool Bno055Uart::send_read(Reg reg, std::size_t len, TimeNs now_ns) {
  const std::size_t n = bno055::encode_read(std::span<std::uint8_t, 4>(tx_.data(), 4), reg, len);
  if (n == 0 || !send(std::span<const std::uint8_t>(tx_.data(), n))) return false;
  const DurationNs wire_ns =
      static_cast<DurationNs>(n + kReadResponseOverhead + len) * port_->byte_time_ns();
  pending_ = {TxnKind::kRead, static_cast<std::uint8_t>(len),
              now_ns + wire_ns + config_.response_timeout_ns, 0};
  return true;
}

bool Bno055Uart::send_write(Reg reg, std::uint8_t value, TimeNs now_ns) {
  const std::array<std::uint8_t, 1> data{value};
  const std::size_t n = bno055::encode_write(tx_, reg, data);
  if (n == 0 || !send(std::span<const std::uint8_t>(tx_.data(), n))) return false;
  const DurationNs wire_ns =
      static_cast<DurationNs>(n + kStatusResponseBytes) * port_->byte_time_ns();
  pending_ = {TxnKind::kWrite, 0, now_ns + wire_ns + config_.response_timeout_ns, 0};
  return true;
}

Bno055Uart::TxnResult Bno055Uart::poll_response(TimeNs now_ns) {
  if (!port_) {
    pending_ = {};
    return TxnResult::kIoError;
  }
  std::array<std::uint8_t, 128> buf{};
  for (;;) {
    const SerialIo io = port_->read_some(buf, 0);
    if (io.bytes > 0) {
      rx_.push(std::span<const std::uint8_t>(buf.data(), io.bytes));
      ++pending_.reads;
      if (io.bytes < buf.size()) break;
      continue;
    }
    if (io.error == ETIMEDOUT) break;  // nothing more for now
    ++uart_.io_errors;
    if (device_gone(io.error)) port_.reset();
    pending_ = {};
    return TxnResult::kIoError;
  }

  const std::size_t expected = pending_.kind == TxnKind::kRead ? pending_.len : 0;
  const bno055::Response r = bno055::parse_response(rx_, expected, data_);
  if (r.garbage_bytes > 0) {
    uart_.garbage_bytes += r.garbage_bytes;
    ++counters_.resync;
  }
  switch (r.kind) {
    case bno055::ResponseKind::kIncomplete:
      if (now_ns < pending_.deadline_ns) return TxnResult::kPending;
      if (!rx_.empty()) ++counters_.short_transfer;  // a frame cut off
      uart_.garbage_bytes += rx_.drop_all();
      ++uart_.timeouts;
      pending_ = {};
      return TxnResult::kTimeout;
    case bno055::ResponseKind::kReadData: {
      ++uart_.responses;
      if (pending_.reads > 1) ++uart_.partial_reads;
      pending_ = {};
      return TxnResult::kData;
    }
    case bno055::ResponseKind::kStatus: {
      ++uart_.responses;
      ++uart_.status[static_cast<std::size_t>(r.status)];
      if (pending_.reads > 1) ++uart_.partial_reads;
      const bool ack = r.status == UartStatus::kWriteSuccess && pending_.kind == TxnKind::kWrite;
      last_status_ = r.status;
      pending_ = {};
      return ack ? TxnResult::kAck : TxnResult::kErrorStatus;
    }
    case bno055::ResponseKind::kBadFrame:
      // No checksum: after a wrong length nothing that follows can be trusted as framing.
      ++counters_.resync;
      uart_.garbage_bytes += 1 + rx_.drop_all();
      pending_ = {};
      return TxnResult::kBadFrame;
  }
  return TxnResult::kPending;
}

bool Bno055Uart::fail(TxnResult r, TimeNs now_ns) {
  ++counters_.bad_transfer;
  if (r == TxnResult::kErrorStatus) ++counters_.nack;
  if (++failures_ > config_.max_failures) {
    enter_reset(now_ns, now_ns + config_.retry_backoff_ns);
    return true;
  }
  return false;
}

void Bno055Uart::succeed() {
  if (failures_ > 0) --failures_;
}

TimeNs Bno055Uart::step_reset(TimeNs now_ns) {
  if (pending_.kind != TxnKind::kNone) {
    // The PAGE_ID ack. Whatever it is (a chip mid-boot may not answer), the reset follows.
    if (poll_response(now_ns) == TxnResult::kPending) return pending_.deadline_ns;
  }
  if (now_ns < not_before_ns_) return not_before_ns_;
  if (!port_ && !try_reopen()) {
    not_before_ns_ = now_ns + std::max(config_.retry_backoff_ns, config_.probe_interval_ns);
    return not_before_ns_;
  }
  if (phase_ == Phase::kResetPage) {
    // SYS_TRIGGER is on page 0; a chip left on page 1 would take the write elsewhere.
    if (send_write(Reg::kPageId, 0, now_ns)) {
      phase_ = Phase::kResetTrigger;
      return pending_.deadline_ns;
    }
    not_before_ns_ = now_ns + config_.retry_backoff_ns;
    return not_before_ns_;
  }
  if (!send_write(Reg::kSysTrigger, bno055::sys_trigger::kRstSys, now_ns)) {
    phase_ = Phase::kResetPage;
    not_before_ns_ = now_ns + config_.retry_backoff_ns;
    return not_before_ns_;
  }
  // The chip may ack before it resets or not at all; a late ack is drained as stale bytes.
  pending_ = {};
  state_ = ImuDriverState::kWaitForReset;
  reset_deadline_ns_ = now_ns + config_.reset_timeout_ns;
  not_before_ns_ = now_ns + config_.probe_interval_ns;
  return not_before_ns_;
}

TimeNs Bno055Uart::step_wait_for_reset(TimeNs now_ns) {
  if (pending_.kind != TxnKind::kNone) {
    const TxnResult r = poll_response(now_ns);
    if (r == TxnResult::kPending) return pending_.deadline_ns;
    if (r == TxnResult::kData) {
      if (data_[0] == bno055::kChipIdValue) {
        state_ = ImuDriverState::kConfigure;
        phase_ = Phase::kConfigMode;
        entry_ = 0;
        failures_ = 0;
        not_before_ns_ = now_ns;
        return step_configure(now_ns);
      }
      ++counters_.probe_failures;  // something answers, but not a BNO055
      enter_reset(now_ns, now_ns + config_.retry_backoff_ns);
      return not_before_ns_;
    }
    // No answer or an error status: expected while the chip boots; ask again later.
    not_before_ns_ = now_ns + config_.probe_interval_ns;
  }
  if (now_ns >= reset_deadline_ns_) {
    ++counters_.probe_failures;
    enter_reset(now_ns, now_ns + config_.retry_backoff_ns);
    return not_before_ns_;
  }
  if (now_ns < not_before_ns_) return std::min(not_before_ns_, reset_deadline_ns_);
  if (send_read(Reg::kChipId, 1, now_ns)) return pending_.deadline_ns;
  if (!port_) {  // gone while booting: start over (RESET reopens it)
    enter_reset(now_ns, now_ns + config_.retry_backoff_ns);
    return not_before_ns_;
  }
  not_before_ns_ = now_ns + config_.probe_interval_ns;
  return not_before_ns_;
}

TimeNs Bno055Uart::step_configure(TimeNs now_ns) {
  if (pending_.kind != TxnKind::kNone) {
    const TxnResult r = poll_response(now_ns);
    if (r == TxnResult::kPending) return pending_.deadline_ns;
    const ConfigEntry& e = config_table_[entry_];
    bool ok = false;
    switch (phase_) {
      case Phase::kConfigMode:
        if ((ok = r == TxnResult::kAck)) {
          phase_ = Phase::kEntryRead;
          entry_ = 0;
          not_before_ns_ = now_ns + bno055::kAnyToConfigNs;
        }
        break;
      case Phase::kEntryRead:
        if ((ok = r == TxnResult::kData)) {
          entry_value_ = data_[0];
          phase_ = Phase::kEntryWrite;
        }
        break;
      case Phase::kEntryWrite:
        if ((ok = r == TxnResult::kAck)) {
          phase_ = Phase::kEntryVerify;
          not_before_ns_ = now_ns + e.settle_ns;
        }
        break;
      case Phase::kEntryVerify:
        if ((ok = r == TxnResult::kData)) {
          if ((data_[0] & (e.set | e.clear)) != e.set) {
            ++counters_.config_mismatch;  // the chip did not take the value
            enter_reset(now_ns, now_ns + config_.retry_backoff_ns);
            return not_before_ns_;
          }
          phase_ = Phase::kEntryRead;
          if (++entry_ == kConfigEntries) {
            enter_run(now_ns);
            return step_run(now_ns);
          }
        }
        break;
      default:
        break;
    }
    if (ok) {
      succeed();
    } else if (fail(r, now_ns)) {
      return not_before_ns_;  // reset
    }
  }
  if (now_ns < not_before_ns_) return not_before_ns_;
  const ConfigEntry& e = config_table_[entry_];
  bool sent = false;
  switch (phase_) {
    case Phase::kConfigMode:
      sent = send_write(Reg::kOprMode, static_cast<std::uint8_t>(bno055::OprMode::kConfig), now_ns);
      break;
    case Phase::kEntryRead:
    case Phase::kEntryVerify:
      sent = send_read(e.reg, 1, now_ns);
      break;
    case Phase::kEntryWrite:
      sent =
          send_write(e.reg, static_cast<std::uint8_t>((entry_value_ & ~e.clear) | e.set), now_ns);
      break;
    default:
      break;
  }
  if (sent) return pending_.deadline_ns;
  if (!fail(TxnResult::kIoError, now_ns)) not_before_ns_ = now_ns + config_.retry_backoff_ns;
  return not_before_ns_;
}

TimeNs Bno055Uart::step_run(TimeNs now_ns) {
  if (pending_.kind != TxnKind::kNone) {
    const TxnResult r = poll_response(now_ns);
    if (r == TxnResult::kPending) return pending_.deadline_ns;
    if (phase_ == Phase::kRunSample) {
      if (r == TxnResult::kData) {
        succeed();
        push_sample(now_ns);
        if (++samples_since_check_ >= kRecheckEvery) {
          samples_since_check_ = 0;
          phase_ = Phase::kRunCheck;
          if (send_read(config_table_[entry_].reg, 1, now_ns)) return pending_.deadline_ns;
          if (fail(TxnResult::kIoError, now_ns)) return not_before_ns_;
        }
      } else if (r == TxnResult::kErrorStatus && last_status_ == UartStatus::kBusOverRunError &&
                 overrun_retries_left_ > 0) {
        // The chip's known answer under load: the read is retried at once, same tick.
        --overrun_retries_left_;
        ++uart_.overrun_retries;
        ++counters_.nack;
        if (send_read(Reg::kAccDataXLsb, bno055::kBurstBytes, now_ns)) {
          return pending_.deadline_ns;
        }
        ++counters_.dropped_samples;
        if (fail(TxnResult::kIoError, now_ns)) return not_before_ns_;
      } else {
        ++counters_.dropped_samples;  // this tick's sample is lost; the next tick reads anew
        if (fail(r, now_ns)) return not_before_ns_;
      }
    } else if (phase_ == Phase::kRunCheck) {
      if (r == TxnResult::kData) {
        succeed();
        ++rechecks_;
        const ConfigEntry& e = config_table_[entry_];
        if ((data_[0] & (e.set | e.clear)) != e.set) {
          ++counters_.config_mismatch;  // changed behind our back (brown-out, reset)
          enter_reset(now_ns, now_ns);
          return now_ns;
        }
        entry_ = (entry_ + 1) % kConfigEntries;
      } else if (fail(r, now_ns)) {
        return not_before_ns_;
      }  // a failed check is repeated for the same entry next time
    }
    phase_ = Phase::kRunIdle;
  }
  if (now_ns < next_tick_ns_) return next_tick_ns_;
  // Ticks that passed while a transaction was out are samples never read.
  const auto missed = static_cast<std::uint64_t>((now_ns - next_tick_ns_) / period_ns_);
  counters_.dropped_samples += missed;
  tick_ += missed;
  next_tick_ns_ += static_cast<DurationNs>(missed + 1) * period_ns_;
  sample_tick_ = tick_++;
  overrun_retries_left_ = config_.max_overrun_retries;
  if (send_read(Reg::kAccDataXLsb, bno055::kBurstBytes, now_ns)) {
    phase_ = Phase::kRunSample;
    return pending_.deadline_ns;
  }
  ++counters_.dropped_samples;
  if (!port_) {  // unplugged: RESET reopens the device node
    enter_reset(now_ns, now_ns + config_.retry_backoff_ns);
    return not_before_ns_;
  }
  if (fail(TxnResult::kIoError, now_ns)) return not_before_ns_;
  return next_tick_ns_;
}

void Bno055Uart::push_sample(TimeNs now_ns) {
  const bno055::RawBurst raw = bno055::unpack_burst(
      std::span<const std::uint8_t, bno055::kBurstBytes>(data_.data(), bno055::kBurstBytes));
  const bno055::ScaledBurst s = bno055::scale_burst(raw, config_.gyro_in_rps);
  // Clock model (header): the registers were latched when the chip processed the request,
  // i.e. the response's wire time and the processing latency before the bytes were here.
  const DurationNs wire_ns = static_cast<DurationNs>(kReadResponseOverhead + bno055::kBurstBytes) *
                             serial_byte_time_ns(config_.baud);
  clock_.observe(sample_tick_, now_ns - wire_ns);
  ImuSample out;
  // The threading contract promises increasing timestamps; the lower envelope may step back
  // when the latency suddenly drops, so the stamp is held just after the previous one.
  out.t_ns = std::max(clock_.time_of(sample_tick_), last_t_ns_ + 1);
  last_t_ns_ = out.t_ns;
  out.publish_t_ns = now_ns;
  out.gyro_rad_s = s.gyro_rad_s;
  out.accel_m_s2 = s.accel_m_s2;
  out.mag_uT = s.mag_uT;
  out.temperature_c = s.temperature_c;
  out.q_chipworld_body = s.q_chipworld_body;
  sink_.on_imu_sample(out);
  ++counters_.samples;
}

}  // namespace wallar::drivers
