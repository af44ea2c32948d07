// SPDX-License-Identifier: Apache-2.0
/// @file icm20948.cpp
/// @brief ICM-20948 state machine, FIFO streaming, edge timestamps, AK09916 through the aux master.
#include "wallar/drivers/imu/icm20948.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace wallar::drivers {

using icm20948::Bank;
using icm20948::FifoRecord;
using icm20948::Reg0;
using icm20948::Reg1;
using icm20948::Reg2;
using icm20948::Reg3;
namespace ak = icm20948::ak09916;

namespace icm20948 {

ScaledRecord scale_record(const FifoRecord& r, AccelRange ar, GyroRange gr) {
  const double a = kStandardGravity / accel_lsb_per_g(ar);
  const double g = (M_PI / 180.0) / gyro_lsb_per_dps(gr);
  ScaledRecord s;
  s.accel_m_s2 =
      Eigen::Vector3d(be16(r.ACCEL_XOUT_H, r.ACCEL_XOUT_L), be16(r.ACCEL_YOUT_H, r.ACCEL_YOUT_L),
                      be16(r.ACCEL_ZOUT_H, r.ACCEL_ZOUT_L)) *
      a;
  s.gyro_rad_s =
      Eigen::Vector3d(be16(r.GYRO_XOUT_H, r.GYRO_XOUT_L), be16(r.GYRO_YOUT_H, r.GYRO_YOUT_L),
                      be16(r.GYRO_ZOUT_H, r.GYRO_ZOUT_L)) *
      g;
  return s;
}

std::optional<Eigen::Vector3d> ak09916_body_uT(std::span<const std::uint8_t, 9> b) {
  if ((b[0] & ak::DRDY) == 0 || (b[8] & ak::HOFL) != 0) return std::nullopt;
  const double x = le16(b[1], b[2]) * ak::kUtPerLsb;
  const double y = le16(b[3], b[4]) * ak::kUtPerLsb;
  const double z = le16(b[5], b[6]) * ak::kUtPerLsb;
  return Eigen::Vector3d(x, -y, -z);  // AK09916 Y, Z point opposite to the accel's (§12)
}

std::uint8_t rate_divider(double rate_hz) {
  if (!(rate_hz > 0.0)) return 0;
  const double div = std::round(kBaseRateHz / rate_hz - 1.0);
  return static_cast<std::uint8_t>(std::clamp(div, 0.0, 255.0));
}

double self_test_factory_response(std::uint8_t otp_code) {
  if (otp_code == 0) return 0.0;
  return 2620.0 * std::pow(1.01, static_cast<double>(otp_code) - 1.0);
}

SelfTestResult evaluate_self_test(const std::array<double, 3>& gyro_off_lsb,
                                  const std::array<double, 3>& gyro_on_lsb,
                                  const std::array<std::uint8_t, 3>& gyro_otp,
                                  const std::array<double, 3>& accel_off_lsb,
                                  const std::array<double, 3>& accel_on_lsb,
                                  const std::array<std::uint8_t, 3>& accel_otp) {
  SelfTestResult r;
  r.gyro_pass = r.accel_pass = true;
  for (std::size_t i = 0; i < 3; ++i) {
    const double g_otp = self_test_factory_response(gyro_otp[i]);
    const double a_otp = self_test_factory_response(accel_otp[i]);
    r.gyro_ratio[i] = g_otp > 0.0 ? (gyro_on_lsb[i] - gyro_off_lsb[i]) / g_otp : 0.0;
    r.accel_ratio[i] = a_otp > 0.0 ? (accel_on_lsb[i] - accel_off_lsb[i]) / a_otp : 0.0;
    r.gyro_pass = r.gyro_pass && r.gyro_ratio[i] >= 0.5 && r.gyro_ratio[i] <= 1.5;
    r.accel_pass = r.accel_pass && r.accel_ratio[i] >= 0.5 && r.accel_ratio[i] <= 1.5;
  }
  return r;
}

namespace {
// Plain register access for the self-test (no state machine, no counters).
bool st_write(I2cDevice& d, Bank bank, std::uint8_t reg, std::uint8_t value) {
  const std::array<std::uint8_t, 2> sel{kRegBankSel, bank_sel_value(bank)};
  const std::array<std::uint8_t, 2> tx{reg, value};
  return d.transfer(sel, {}) == 0 && d.transfer(tx, {}) == 0;
}
bool st_read(I2cDevice& d, Bank bank, std::uint8_t reg, std::span<std::uint8_t> out) {
  const std::array<std::uint8_t, 2> sel{kRegBankSel, bank_sel_value(bank)};
  const std::array<std::uint8_t, 1> tx{reg};
  return d.transfer(sel, {}) == 0 && d.transfer(tx, out) == 0;
}
// Mean accel (0..2) and gyro (3..5) output in LSB over n reads, one per wait(period).
bool st_average(I2cDevice& d, const std::function<void(DurationNs)>& wait, int n,
                std::array<double, 6>& mean) {
  mean.fill(0.0);
  for (int i = 0; i < n; ++i) {
    std::array<std::uint8_t, 12> b{};
    if (!st_read(d, Bank::k0, static_cast<std::uint8_t>(Reg0::ACCEL_XOUT_H), b)) return false;
    for (std::size_t a = 0; a < 6; ++a) mean[a] += be16(b[2 * a], b[2 * a + 1]);
    wait(kNsPerMs);
  }
  for (double& m : mean) m /= std::max(n, 1);
  return true;
}
}  // namespace

std::optional<SelfTestResult> run_self_test(I2cDevice& device,
                                            const std::function<void(DurationNs)>& wait,
                                            int samples, DurationNs settle_ns) {
  const auto r2 = [](Reg2 r) { return static_cast<std::uint8_t>(r); };
  // Awake, all axes on, 1125 Hz, DLPF on, the self-test ranges (±250 dps, ±2 g).
  if (!st_write(device, Bank::k0, static_cast<std::uint8_t>(Reg0::PWR_MGMT_1), CLKSEL_AUTO) ||
      !st_write(device, Bank::k0, static_cast<std::uint8_t>(Reg0::PWR_MGMT_2), 0x00) ||
      !st_write(device, Bank::k2, r2(Reg2::GYRO_SMPLRT_DIV), 0) ||
      !st_write(device, Bank::k2, r2(Reg2::GYRO_CONFIG_1), gyro_dlpfcfg(1) | GYRO_FCHOICE) ||
      !st_write(device, Bank::k2, r2(Reg2::ACCEL_CONFIG), accel_dlpfcfg(1) | ACCEL_FCHOICE) ||
      !st_write(device, Bank::k2, r2(Reg2::GYRO_CONFIG_2), 0) ||
      !st_write(device, Bank::k2, r2(Reg2::ACCEL_CONFIG_2), 0)) {
    return std::nullopt;
  }
  wait(settle_ns);
  std::array<double, 6> off{};
  if (!st_average(device, wait, samples, off)) return std::nullopt;
  if (!st_write(device, Bank::k2, r2(Reg2::GYRO_CONFIG_2), XGYRO_CTEN | YGYRO_CTEN | ZGYRO_CTEN) ||
      !st_write(device, Bank::k2, r2(Reg2::ACCEL_CONFIG_2),
                AX_ST_EN_REG | AY_ST_EN_REG | AZ_ST_EN_REG)) {
    return std::nullopt;
  }
  wait(settle_ns);
  std::array<double, 6> on{};
  const bool measured = st_average(device, wait, samples, on);
  // Self-test off again whatever happened.
  const bool cleared = st_write(device, Bank::k2, r2(Reg2::GYRO_CONFIG_2), 0) &&
                       st_write(device, Bank::k2, r2(Reg2::ACCEL_CONFIG_2), 0);
  std::array<std::uint8_t, 3> gyro_otp{};
  std::array<std::uint8_t, 3> accel_otp{};
  if (!measured || !cleared ||
      !st_read(device, Bank::k1, static_cast<std::uint8_t>(Reg1::SELF_TEST_X_GYRO), gyro_otp) ||
      !st_read(device, Bank::k1, static_cast<std::uint8_t>(Reg1::SELF_TEST_X_ACCEL), accel_otp)) {
    return std::nullopt;
  }
  return evaluate_self_test({off[3], off[4], off[5]}, {on[3], on[4], on[5]}, gyro_otp,
                            {off[0], off[1], off[2]}, {on[0], on[1], on[2]}, accel_otp);
}

}  // namespace icm20948

namespace {
constexpr DurationNs kResetWaitNs = 1 * kNsPerMs;       // DEVICE_RESET to first probe
constexpr DurationNs kProbeRetryNs = 1 * kNsPerMs;      // WHO_AM_I retry period
constexpr DurationNs kResetTimeoutNs = 100 * kNsPerMs;  // WAIT_FOR_RESET gives up
constexpr DurationNs kRetryNs = 10 * kNsPerMs;          // after a failed RESET write
constexpr DurationNs kSlv4WaitNs = 1 * kNsPerMs;        // one aux-bus byte at 345.6 kHz: ~100 us
constexpr DurationNs kSlv4TimeoutNs = 20 * kNsPerMs;
// EXT_SLV_SENS_DATA read period: half the AK09916's 10 ms, so no measurement is missed.
constexpr DurationNs kMagPollNs = 5 * kNsPerMs;
// One configuration register re-checked per period, round-robin (the whole table in ~0.2 s).
constexpr DurationNs kRecheckPeriodNs = 10 * kNsPerMs;
constexpr int kConfigureAttempts = 3;
constexpr unsigned kEdgeLagRecords = 2;  // records without edges before edges count as missed
constexpr std::uint8_t kDlpfCfg = 1;     // gyro 196.6 Hz / accel 246 Hz 3 dB (tables 16, 18)

template <typename R>
constexpr std::uint8_t u8(R r) {
  return static_cast<std::uint8_t>(r);
}
}  // namespace

Icm20948::Icm20948(I2cDevice& device, const Config& config, ImuSampleSink& sink)
    : device_(device),
      config_(config),
      sink_(sink),
      divider_(icm20948::rate_divider(config.rate_hz)),
      rate_hz_(icm20948::rate_of_divider(divider_)),
      period_ns_(static_cast<DurationNs>(std::llround(1e9 / rate_hz_))),
      clock_(period_ns_) {
  config_.fifo_read_every =
      std::clamp<unsigned>(config_.fifo_read_every, 1, icm20948::kFifoMaxRecords / 2);
  using namespace icm20948;  // NOLINT(google-build-using-namespace): the bit names
  const auto add = [this](Bank b, std::uint8_t reg, std::uint8_t set, std::uint8_t clear) {
    table_[table_size_++] = ConfigEntry{b, reg, set, clear};
  };
  const auto full = [&add](Bank b, std::uint8_t reg, std::uint8_t v) {
    add(b, reg, v, static_cast<std::uint8_t>(~v));
  };
  const bool mag = config_.mag_enabled;
  add(Bank::k0, u8(Reg0::PWR_MGMT_1), CLKSEL_AUTO,
      u8(DEVICE_RESET | SLEEP | LP_EN | TEMP_DIS | (CLKSEL_MASK & ~CLKSEL_AUTO)));
  full(Bank::k0, u8(Reg0::PWR_MGMT_2), 0x00);  // all accel and gyro axes on
  add(Bank::k0, u8(Reg0::USER_CTRL), u8(FIFO_EN | (mag ? I2C_MST_EN : 0)),
      u8(DMP_EN | I2C_IF_DIS | (mag ? 0 : I2C_MST_EN)));
  // INT1: active high, push-pull, 50 us pulse per sample (the edge is the sample time).
  add(Bank::k0, u8(Reg0::INT_PIN_CFG), 0, u8(INT1_ACTL | INT1_OPEN | INT1_LATCH_EN | BYPASS_EN));
  full(Bank::k0, u8(Reg0::INT_ENABLE_1), RAW_DATA_0_RDY_EN);
  full(Bank::k0, u8(Reg0::FIFO_EN_1), 0x00);
  full(Bank::k0, u8(Reg0::FIFO_EN_2),
       u8(ACCEL_FIFO_EN | GYRO_X_FIFO_EN | GYRO_Y_FIFO_EN | GYRO_Z_FIFO_EN));
  // Snapshot: a full FIFO stops instead of overwriting its oldest bytes mid-record.
  add(Bank::k0, u8(Reg0::FIFO_MODE), FIFO_MODE_SNAPSHOT, 0);
  full(Bank::k2, u8(Reg2::GYRO_SMPLRT_DIV), divider_);
  full(Bank::k2, u8(Reg2::GYRO_CONFIG_1),
       u8(gyro_dlpfcfg(kDlpfCfg) | gyro_fs_sel(u8(config_.gyro_range)) | GYRO_FCHOICE));
  add(Bank::k2, u8(Reg2::ACCEL_SMPLRT_DIV_1), 0, 0x0F);
  full(Bank::k2, u8(Reg2::ACCEL_SMPLRT_DIV_2), divider_);
  full(Bank::k2, u8(Reg2::ACCEL_CONFIG),
       u8(accel_dlpfcfg(kDlpfCfg) | accel_fs_sel(u8(config_.accel_range)) | ACCEL_FCHOICE));
  if (mag) {
    add(Bank::k3, u8(Reg3::I2C_MST_CTRL), u8(I2C_MST_P_NSR | I2C_MST_CLK_345_6KHZ),
        u8(I2C_MST_CLK_MASK & ~I2C_MST_CLK_345_6KHZ));
    // Aux reads at 1100 Hz / 2^3 = 137.5 Hz, faster than the magnetometer's 100 Hz.
    add(Bank::k3, u8(Reg3::I2C_MST_ODR_CONFIG), 0x03, 0x0C);
    full(Bank::k3, u8(Reg3::I2C_SLV0_ADDR), u8(kI2cSlvRnw | ak::kAddress));
    full(Bank::k3, u8(Reg3::I2C_SLV0_REG), u8(ak::Reg::ST1));
    full(Bank::k3, u8(Reg3::I2C_SLV0_CTRL), u8(I2C_SLV_EN | ak::kBurstLength));
  }
}

// ---- Bus helpers ---------------------------------------------------------------------------

bool Icm20948::transfer(std::span<const std::uint8_t> tx, std::span<std::uint8_t> rx,
                        bool repeatable) {
  const int err = repeatable ? device_.transfer(tx, rx) : device_.transfer_once(tx, rx);
  last_error_ = err;
  if (err == 0) {
    if (failures_ > 0) --failures_;
    return true;
  }
  if (is_i2c_nack(err)) {
    ++counters_.nack;
  } else if (err == kI2cShortTransfer) {
    ++counters_.short_transfer;
  } else {
    ++counters_.bad_transfer;
  }
  ++failures_;
  bank_ = -1;  // a failed bank write leaves the bank unknown
  return false;
}

bool Icm20948::select_bank(Bank bank) {
  if (bank_ == static_cast<int>(bank)) return true;
  const std::array<std::uint8_t, 2> tx{icm20948::kRegBankSel, icm20948::bank_sel_value(bank)};
  if (!transfer(tx, {})) return false;
  bank_ = static_cast<int>(bank);
  return true;
}

bool Icm20948::read(Bank bank, std::uint8_t reg, std::span<std::uint8_t> out, bool repeatable) {
  if (!select_bank(bank)) return false;
  const std::array<std::uint8_t, 1> tx{reg};
  return transfer(tx, out, repeatable);
}

bool Icm20948::write(Bank bank, std::uint8_t reg, std::uint8_t value) {
  if (!select_bank(bank)) return false;
  const std::array<std::uint8_t, 2> tx{reg, value};
  return transfer(tx, {});
}

bool Icm20948::write_entry(const ConfigEntry& e) {
  std::array<std::uint8_t, 1> v{};
  if (!read(e.bank, e.reg, v)) return false;
  const auto value = static_cast<std::uint8_t>((v[0] | e.set_bits) & ~e.clear_bits);
  return value == v[0] || write(e.bank, e.reg, value);
}

bool Icm20948::entry_ok(const ConfigEntry& e, bool& ok) {
  std::array<std::uint8_t, 1> v{};
  if (!read(e.bank, e.reg, v)) return false;
  ok = (v[0] & e.set_bits) == e.set_bits && (v[0] & e.clear_bits) == 0;
  return true;
}

bool Icm20948::slv4(std::uint8_t addr, std::uint8_t reg, std::uint8_t dout) {
  return write(Bank::k3, u8(Reg3::I2C_SLV4_ADDR), addr) &&
         write(Bank::k3, u8(Reg3::I2C_SLV4_REG), reg) &&
         write(Bank::k3, u8(Reg3::I2C_SLV4_DO), dout) &&
         write(Bank::k3, u8(Reg3::I2C_SLV4_CTRL), icm20948::I2C_SLV_EN);
}

// ---- State machine -------------------------------------------------------------------------

void Icm20948::enter_reset(TimeNs now_ns) {
  if (!first_reset_) ++counters_.resets;
  first_reset_ = false;
  state_ = ImuDriverState::kReset;
  t_state_ns_ = now_ns;
  failures_ = 0;
  polling_ = false;
}

bool Icm20948::check_failures(TimeNs now_ns) {
  if (failures_ <= config_.failure_limit) return false;
  enter_reset(now_ns);
  return true;
}

TimeNs Icm20948::step(TimeNs now_ns, std::optional<TimeNs> data_ready_ns) {
  if (first_reset_) enter_reset(now_ns);
  TimeNs next = now_ns + kRetryNs;
  switch (state_) {
    case ImuDriverState::kReset:
      next = step_reset(now_ns);
      break;
    case ImuDriverState::kWaitForReset:
      next = step_wait_for_reset(now_ns);
      break;
    case ImuDriverState::kConfigure:
      next = step_configure(now_ns);
      break;
    case ImuDriverState::kRun:
      next = step_run(now_ns, data_ready_ns);
      break;
  }
  if (check_failures(now_ns)) return now_ns + kRetryNs;
  return next;
}

TimeNs Icm20948::step_reset(TimeNs now_ns) {
  bank_ = -1;
  // Select bank 0 explicitly: the bank survives everything but a reset or power cycle.
  if (!write(Bank::k0, u8(Reg0::PWR_MGMT_1), icm20948::DEVICE_RESET)) {
    failures_ = 0;  // RESET retries forever (an unplugged device), slowly
    return now_ns + kRetryNs;
  }
  bank_ = 0;  // the reset selects bank 0
  state_ = ImuDriverState::kWaitForReset;
  t_state_ns_ = now_ns;
  return now_ns + kResetWaitNs;
}

TimeNs Icm20948::step_wait_for_reset(TimeNs now_ns) {
  std::array<std::uint8_t, 1> who{};
  std::array<std::uint8_t, 1> pwr{};
  const bool answered =
      read(Bank::k0, u8(Reg0::WHO_AM_I), who) && read(Bank::k0, u8(Reg0::PWR_MGMT_1), pwr);
  if (answered && who[0] == icm20948::kWhoAmIValue && pwr[0] == icm20948::kPwrMgmt1ResetValue) {
    state_ = ImuDriverState::kConfigure;
    phase_ = ConfigPhase::kTable;
    configure_attempts_ = 0;
    t_state_ns_ = now_ns;
    failures_ = 0;
    return now_ns;  // configure at once
  }
  ++counters_.probe_failures;
  failures_ = 0;  // the probe has its own timeout
  if (now_ns - t_state_ns_ > kResetTimeoutNs) {
    enter_reset(now_ns);
    return now_ns + kRetryNs;
  }
  return now_ns + kProbeRetryNs;
}

TimeNs Icm20948::step_configure(TimeNs now_ns) {
  using namespace icm20948;  // NOLINT(google-build-using-namespace): the bit names
  switch (phase_) {
    case ConfigPhase::kTable: {
      bool all_ok = true;
      for (std::size_t i = 0; i < table_size_; ++i) {
        if (!write_entry(table_[i])) return now_ns + kProbeRetryNs;
      }
      for (std::size_t i = 0; i < table_size_; ++i) {
        bool ok = false;
        if (!entry_ok(table_[i], ok)) return now_ns + kProbeRetryNs;
        all_ok = all_ok && ok;
      }
      if (!all_ok) {
        ++counters_.config_mismatch;
        if (++configure_attempts_ >= kConfigureAttempts) enter_reset(now_ns);
        return now_ns + kProbeRetryNs;
      }
      mag_ok_ = false;
      phase_ = config_.mag_enabled ? ConfigPhase::kMagProbe : ConfigPhase::kFifoStart;
      return now_ns;
    }
    case ConfigPhase::kMagProbe:
    case ConfigPhase::kMagMode: {
      const bool probe = phase_ == ConfigPhase::kMagProbe;
      // Clear a stale SLV4_DONE by reading the status, then start the one-shot transfer.
      std::array<std::uint8_t, 1> st{};
      if (!read(Bank::k0, u8(Reg0::I2C_MST_STATUS), st)) return now_ns + kProbeRetryNs;
      const bool started = probe ? slv4(u8(kI2cSlvRnw | ak::kAddress), u8(ak::Reg::WIA2), 0)
                                 : slv4(ak::kAddress, u8(ak::Reg::CNTL2), ak::CONTINUOUS_100HZ);
      if (!started) return now_ns + kProbeRetryNs;
      phase_ = probe ? ConfigPhase::kMagProbeCheck : ConfigPhase::kMagModeCheck;
      t_state_ns_ = now_ns;
      return now_ns + kSlv4WaitNs;
    }
    case ConfigPhase::kMagProbeCheck:
    case ConfigPhase::kMagModeCheck: {
      const bool probe = phase_ == ConfigPhase::kMagProbeCheck;
      std::array<std::uint8_t, 1> st{};
      if (!read(Bank::k0, u8(Reg0::I2C_MST_STATUS), st)) return now_ns + kProbeRetryNs;
      bool failed = (st[0] & I2C_SLV4_NACK) != 0;
      if (!failed && (st[0] & I2C_SLV4_DONE) == 0) {
        if (now_ns - t_state_ns_ < kSlv4TimeoutNs) return now_ns + kSlv4WaitNs;
        failed = true;
      }
      if (!failed && probe) {
        std::array<std::uint8_t, 1> di{};
        if (!read(Bank::k3, u8(Reg3::I2C_SLV4_DI), di)) return now_ns + kProbeRetryNs;
        failed = di[0] != ak::kWia2Value;
      }
      if (failed) {
        // The magnetometer is optional: stream accel and gyro without it.
        ++mag_probe_failures_;
        phase_ = ConfigPhase::kFifoStart;
        return now_ns;
      }
      if (probe) {
        phase_ = ConfigPhase::kMagMode;
      } else {
        mag_ok_ = true;
        phase_ = ConfigPhase::kFifoStart;
      }
      return now_ns;
    }
    case ConfigPhase::kFifoStart: {
      if (!write(Bank::k0, u8(Reg0::FIFO_RST), FIFO_RESET) ||
          !write(Bank::k0, u8(Reg0::FIFO_RST), 0x00)) {
        return now_ns + kProbeRetryNs;
      }
      std::array<std::uint8_t, 1> st{};
      if (!read(Bank::k0, u8(Reg0::INT_STATUS_2), st)) return now_ns + kProbeRetryNs;  // clear
      state_ = ImuDriverState::kRun;
      t_state_ns_ = now_ns;
      clock_.reset();
      k_next_ = k_edge_next_ = 0;
      pending_edges_ = 0;
      t_last_wake_edge_ns_ = now_ns;
      polling_ = !config_.has_data_ready;
      have_last_sample_ = false;
      t_mag_read_ns_ = now_ns;
      last_mag_burst_.fill(0);
      recheck_ = 0;
      t_recheck_ns_ = now_ns;
      return now_ns + (config_.has_data_ready ? 4 * period_ns_ : period_ns_);
    }
  }
  return now_ns + kProbeRetryNs;
}

TimeNs Icm20948::step_run(TimeNs now_ns, std::optional<TimeNs> data_ready_ns) {
  const DurationNs overdue_ns = 3 * period_ns_ + period_ns_ / 2;
  const DurationNs poll_ns = static_cast<DurationNs>(config_.fifo_read_every) * period_ns_;
  bool read_now = false;
  if (data_ready_ns) {
    ++pending_edges_;
    t_last_edge_ns_ = *data_ready_ns;
    t_last_wake_edge_ns_ = *data_ready_ns;
    if (polling_ && config_.has_data_ready) polling_ = false;  // edges are back
    read_now = pending_edges_ >= config_.fifo_read_every;
  } else if (config_.has_data_ready && !polling_ && now_ns - t_last_wake_edge_ns_ >= overdue_ns) {
    polling_ = true;  // no edge for more than 3 periods: read on our own timer
    read_now = true;
  } else {
    read_now = polling_;
  }
  if (read_now) {
    read_fifo(now_ns, data_ready_ns.has_value());
    if (state_ != ImuDriverState::kRun) return now_ns + kRetryNs;
  }
  if (polling_) return now_ns + poll_ns;
  return std::max(now_ns, t_last_wake_edge_ns_ + overdue_ns);
}

void Icm20948::flush_fifo(TimeNs now_ns, bool edge, bool overflow) {
  using namespace icm20948;  // NOLINT(google-build-using-namespace)
  // Samples lost: all the chip made since the last one pushed, up to the newest (at the edge,
  // or at most now), by elapsed time at the estimated period.
  const TimeNs t_newest = edge ? t_last_edge_ns_ : now_ns;
  std::uint64_t lost = 0;
  if (have_last_sample_ && t_newest > t_last_sample_ns_) {
    const double periods = static_cast<double>(t_newest - t_last_sample_ns_) / clock_.period_ns();
    lost = static_cast<std::uint64_t>(edge ? std::llround(periods) : std::floor(periods + 1e-3));
    t_last_sample_ns_ += static_cast<TimeNs>(static_cast<double>(lost) * clock_.period_ns());
  } else {
    // Nothing pushed yet since the FIFO started: count from the FIFO start (index 0).
    const double periods = static_cast<double>(t_newest - t_state_ns_) / clock_.period_ns();
    lost = static_cast<std::uint64_t>(std::max(0.0, std::floor(periods + 1e-3)));
    have_last_sample_ = true;
    t_last_sample_ns_ =
        t_state_ns_ + static_cast<TimeNs>(static_cast<double>(lost) * clock_.period_ns());
  }
  if (overflow)
    ++counters_.fifo_overflow;
  else
    ++counters_.resync;
  counters_.dropped_samples += lost;
  k_next_ += lost;
  k_edge_next_ = k_next_;
  pending_edges_ = 0;
  clock_.reset();  // re-anchor at the next edge
  // Empty the FIFO (a failure here is counted; the next read sees the overflow again).
  if (write(Bank::k0, u8(Reg0::FIFO_RST), FIFO_RESET)) write(Bank::k0, u8(Reg0::FIFO_RST), 0x00);
}

TimeNs Icm20948::read_fifo(TimeNs now_ns, bool edge) {
  using namespace icm20948;  // NOLINT(google-build-using-namespace)
  constexpr std::size_t kRecord = sizeof(FifoRecord);
  // fifo_buf_ holds FIFO_COUNTH, FIFO_COUNTL, then the records: one burst from FIFO_COUNTH
  // reads the count and goes on into FIFO_R_W, where the chip's address pointer stops (PX4's
  // ICM-20948 driver reads the same way).
  const std::span<std::uint8_t> count_buf(fifo_buf_.data(), kFifoCountBytes);
  std::uint8_t* const records = fifo_buf_.data() + kFifoCountBytes;
  const std::size_t max_read = device_.max_read_bytes();
  // FIFO_R_W hands out the next byte on every read, so a burst the bus cannot carry in one
  // transfer (an SMBus-only adapter: 32 bytes) goes as several, each of whole records.
  const std::size_t chunk =
      max_read >= kRecord ? max_read / kRecord * kRecord : std::max<std::size_t>(max_read, 1);
  // The edges since the last read announce that many records: read them with the count.
  const std::size_t announced =
      polling_ ? 0 : std::min<std::size_t>(pending_edges_, kFifoMaxRecords);
  std::size_t got = 0;  // records read so far
  if (announced > 0 && max_read >= kFifoCountBytes + kRecord) {
    got = std::min(announced, (max_read - kFifoCountBytes) / kRecord);
    // Never retried: the bytes clocked out of FIFO_R_W before a failure are gone, and a
    // retry would cut records at the wrong boundaries. Only a NACK moved nothing.
    if (!read(Bank::k0, u8(Reg0::FIFO_COUNTH),
              std::span<std::uint8_t>(fifo_buf_.data(), kFifoCountBytes + got * kRecord), false)) {
      if (!is_i2c_nack(last_error_)) flush_fifo(now_ns, edge, false);
      return now_ns;
    }
  } else if (!read(Bank::k0, u8(Reg0::FIFO_COUNTH), count_buf)) {
    return now_ns;  // the count alone is an ordinary register pair: the bus retries it
  }
  const std::size_t count =
      (static_cast<std::size_t>(count_buf[0] & kFifoCountHMask) << 8) | count_buf[1];
  // A FIFO in snapshot mode stops when the next record does not fit: samples were lost.
  if (count + kRecord > kFifoSize) {
    flush_fifo(now_ns, edge, true);
    return now_ns;
  }
  const std::size_t n = std::min(count / kRecord, kFifoMaxRecords);
  if (n < got) {
    // The burst read past the records the FIFO held (stale edges): a record the chip wrote
    // during it may have been cut. Start the FIFO over.
    flush_fifo(now_ns, edge, false);
    return now_ns;
  }
  if (n == 0) return now_ns;  // a partial record stays in the FIFO until it is whole
  // More records than edges announced (missed edges, or polling): read the rest.
  const std::array<std::uint8_t, 1> fifo_reg{u8(Reg0::FIFO_R_W)};
  bool read_ok = got == n || select_bank(Bank::k0);
  for (std::size_t at = got * kRecord; read_ok && at < n * kRecord; at += chunk) {
    read_ok = transfer(
        fifo_reg, std::span<std::uint8_t>(records + at, std::min(chunk, n * kRecord - at)), false);
  }
  if (!read_ok) {
    // Some bytes may have left the FIFO: record boundaries are lost, start it over.
    flush_fifo(now_ns, edge, false);
    return now_ns;
  }

  // Pair the newest edge with its record (edges and records in order), or observe the read
  // time when no edge came.
  const std::uint64_t produced = k_next_ + n;  // records made so far (+ the ones still inside)
  if (pending_edges_ > 0) {
    std::uint64_t k_edge = k_edge_next_ + pending_edges_ - 1;
    if (k_edge >= produced) {
      clock_.reset();  // more edges than records: stale edges; trust the newest one
      k_edge = produced - 1;
    } else if (k_edge + 1 + kEdgeLagRecords < produced) {
      counters_.missed_data_ready += produced - 1 - k_edge;  // records whose edge never came
      k_edge = produced - 1;
    }
    clock_.observe(k_edge, t_last_edge_ns_);
    k_edge_next_ = k_edge + 1;
    pending_edges_ = 0;
  } else {
    if (config_.has_data_ready && produced > k_edge_next_) {
      counters_.missed_data_ready += produced - k_edge_next_;
    }
    k_edge_next_ = std::max(k_edge_next_, produced);
    clock_.observe(produced - 1, now_ns);
  }

  // The magnetometer's latest aux-bus copy: fresh when DRDY is set and it is new.
  std::optional<Eigen::Vector3d> mag_uT;
  if (mag_ok_ && now_ns - t_mag_read_ns_ >= kMagPollNs) {
    std::array<std::uint8_t, ak::kBurstLength> burst{};
    if (read(Bank::k0, u8(Reg0::EXT_SLV_SENS_DATA_00), burst)) {
      t_mag_read_ns_ = now_ns;
      if (burst != last_mag_burst_) {
        last_mag_burst_ = burst;
        mag_uT = ak09916_body_uT(std::span<const std::uint8_t, 9>(burst));
      }
    }
  }

  for (std::size_t i = 0; i < n; ++i) {
    FifoRecord r;
    std::memcpy(&r, records + i * kRecord, kRecord);
    const ScaledRecord s = scale_record(r, config_.accel_range, config_.gyro_range);
    ImuSample sample;
    sample.t_ns = clock_.time_of(k_next_ + i);
    sample.publish_t_ns = now_ns;
    sample.accel_m_s2 = s.accel_m_s2;
    sample.gyro_rad_s = s.gyro_rad_s;
    if (i + 1 == n && mag_uT) sample.mag_uT = mag_uT;
    sink_.on_imu_sample(sample);
    ++counters_.samples;
    t_last_sample_ns_ = sample.t_ns;
  }
  have_last_sample_ = true;
  k_next_ += n;

  // One configuration register re-checked per period, round-robin.
  if (now_ns - t_recheck_ns_ < kRecheckPeriodNs) return now_ns;
  t_recheck_ns_ = now_ns;
  const ConfigEntry& e = table_[recheck_];
  recheck_ = (recheck_ + 1) % table_size_;
  bool ok = true;
  if (entry_ok(e, ok) && !ok) {
    ++counters_.config_mismatch;
    enter_reset(now_ns);
  }
  return now_ns;
}

}  // namespace wallar::drivers
