// SPDX-License-Identifier: Apache-2.0
/// @file icm20948_sim.cpp
/// @brief The register-level ICM-20948 + AK09916 simulator behind the I2cAdapter seam.
#include "icm20948_sim.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>

#include "wallar/drivers/imu/icm20948_registers.hpp"

namespace wallar::test {
namespace {
namespace reg = drivers::icm20948;
namespace ak = drivers::icm20948::ak09916;
using reg::Reg0;
using reg::Reg1;
using reg::Reg2;
using reg::Reg3;

template <typename R>
constexpr std::uint8_t u8(R r) {
  return static_cast<std::uint8_t>(r);
}

constexpr double kG = 9.80665;  // standard gravity [m/s^2 per g]

std::int16_t quantize(double v) {
  return static_cast<std::int16_t>(std::clamp(std::lround(v), -32768L, 32767L));
}
}  // namespace

Icm20948Sim::Icm20948Sim(std::uint16_t address, SimTruthFn truth)
    : address_(address), truth_(std::move(truth)) {
  if (!truth_) truth_ = [](std::uint64_t, TimeNs) { return SimTruth{}; };
  power_on_reset();
}

void Icm20948Sim::power_on_reset() {
  for (auto& b : regs_) b.fill(0);
  regs_[0][u8(Reg0::WHO_AM_I)] = reg::kWhoAmIValue;
  regs_[0][u8(Reg0::PWR_MGMT_1)] = reg::kPwrMgmt1ResetValue;
  regs_[2][u8(Reg2::GYRO_CONFIG_1)] = 0x01;
  regs_[2][u8(Reg2::ACCEL_CONFIG)] = 0x01;
  // Factory self-test trim (bank 1): plausible codes.
  for (std::uint8_t r :
       {u8(Reg1::SELF_TEST_X_GYRO), u8(Reg1::SELF_TEST_Y_GYRO), u8(Reg1::SELF_TEST_Z_GYRO),
        u8(Reg1::SELF_TEST_X_ACCEL), u8(Reg1::SELF_TEST_Y_ACCEL), u8(Reg1::SELF_TEST_Z_ACCEL)}) {
    regs_[1][r] = 0x80;
  }
  fifo_head_ = fifo_size_ = 0;
  was_awake_ = false;
  ak_.fill(0);
  ak_[u8(ak::Reg::WIA1)] = 0x48;
  ak_[u8(ak::Reg::WIA2)] = ak::kWia2Value;
}

bool Icm20948Sim::awake() const {
  return (regs_[0][u8(Reg0::PWR_MGMT_1)] & (reg::SLEEP | reg::DEVICE_RESET)) == 0;
}

DurationNs Icm20948Sim::period_ns() const {
  const double div = regs_[2][u8(Reg2::GYRO_SMPLRT_DIV)];
  return static_cast<DurationNs>(
      std::llround((1.0 + div) / reg::kBaseRateHz * 1e9 * (1.0 + rate_error_)));
}

std::optional<TimeNs> Icm20948Sim::next_sample_time() const {
  if (!awake() || unplugged_) return std::nullopt;
  return next_sample_ns_;
}

bool Icm20948Sim::data_ready_enabled() const {
  return (regs_[0][u8(Reg0::INT_ENABLE_1)] & reg::RAW_DATA_0_RDY_EN) != 0;
}

void Icm20948Sim::set_unplugged(bool unplugged) {
  if (unplugged_ && !unplugged) power_on_reset();  // power comes back: a fresh chip
  unplugged_ = unplugged;
}

void Icm20948Sim::inject(Fault fault, int count) {
  for (int i = 0; i < count; ++i) faults_.push_back(fault);
}

std::uint64_t Icm20948Sim::fifo_samples_between(TimeNs t0, TimeNs t1) const {
  return static_cast<std::uint64_t>(std::count_if(
      samples_.begin(), samples_.end(),
      [t0, t1](const SimSample& s) { return s.to_fifo && s.t_ns > t0 && s.t_ns <= t1; }));
}

void Icm20948Sim::advance_to(TimeNs t_ns) {
  while (awake() && !unplugged_ && next_sample_ns_ <= t_ns) {
    make_sample(next_sample_ns_);
    next_sample_ns_ += period_ns();
  }
  now_ns_ = std::max(now_ns_, t_ns);
}

void Icm20948Sim::fifo_push(std::uint8_t b) {
  fifo_[(fifo_head_ + fifo_size_) % fifo_.size()] = b;
  ++fifo_size_;
}

std::uint8_t Icm20948Sim::fifo_pop() {
  if (fifo_size_ == 0) return 0xFF;
  const std::uint8_t b = fifo_[fifo_head_];
  fifo_head_ = (fifo_head_ + 1) % fifo_.size();
  --fifo_size_;
  return b;
}

void Icm20948Sim::make_sample(TimeNs t_ns) {
  const SimTruth truth = truth_(k_, t_ns);
  const auto afs = (regs_[2][u8(Reg2::ACCEL_CONFIG)] >> 1) & 0x03;
  const auto gfs = (regs_[2][u8(Reg2::GYRO_CONFIG_1)] >> 1) & 0x03;
  const double a_lsb = 16384.0 / (1 << afs) / kG;
  const std::array<double, 4> g_lsb_dps{131.0, 65.5, 32.8, 16.4};
  const double g_lsb = g_lsb_dps[gfs] * 180.0 / M_PI;
  SimSample s;
  s.k = k_++;
  s.t_ns = t_ns;
  for (int i = 0; i < 3; ++i) {
    s.accel[i] = quantize(truth.accel_m_s2[i] * a_lsb);
    s.gyro[i] = quantize(truth.gyro_rad_s[i] * g_lsb);
  }
  // Self-test: the electrostatic actuation adds the factory response (2620 * 1.01^(code - 1)
  // LSB at the ±250 dps / ±2 g ranges, less at wider ranges).
  const std::uint8_t gst = regs_[2][u8(Reg2::GYRO_CONFIG_2)];
  const std::uint8_t ast = regs_[2][u8(Reg2::ACCEL_CONFIG_2)];
  for (int i = 0; i < 3; ++i) {
    const auto response = [this](std::uint8_t code, int fs) {
      return std::pow(1.01, code - 1.0) * 2620.0 * self_test_gain_ / (1 << fs);
    };
    if (gst & (reg::XGYRO_CTEN >> i)) {
      s.gyro[i] = quantize(s.gyro[i] + response(regs_[1][u8(Reg1::SELF_TEST_X_GYRO) + i], gfs));
    }
    if (ast & (reg::AX_ST_EN_REG >> i)) {
      s.accel[i] = quantize(s.accel[i] + response(regs_[1][u8(Reg1::SELF_TEST_X_ACCEL) + i], afs));
    }
  }
  const std::int16_t temp = quantize((truth.temperature_c - 21.0) * 333.87 + 21.0);
  // Output registers, big-endian, in register order (accel, gyro, temperature).
  std::array<std::uint8_t, 14> out{};
  for (int i = 0; i < 3; ++i) {
    out[2 * i] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(s.accel[i]) >> 8);
    out[2 * i + 1] = static_cast<std::uint8_t>(s.accel[i] & 0xFF);
    out[6 + 2 * i] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(s.gyro[i]) >> 8);
    out[6 + 2 * i + 1] = static_cast<std::uint8_t>(s.gyro[i] & 0xFF);
  }
  out[12] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(temp) >> 8);
  out[13] = static_cast<std::uint8_t>(temp & 0xFF);
  std::copy(out.begin(), out.end(), regs_[0].begin() + u8(Reg0::ACCEL_XOUT_H));

  // The FIFO records the enabled sensors in register order.
  const std::uint8_t en = regs_[0][u8(Reg0::FIFO_EN_2)];
  if ((regs_[0][u8(Reg0::USER_CTRL)] & reg::FIFO_EN) != 0 && (en & 0x1F) != 0) {
    std::array<std::uint8_t, 14> rec{};
    std::size_t n = 0;
    if (en & reg::ACCEL_FIFO_EN)
      for (int i = 0; i < 6; ++i) rec[n++] = out[i];
    if (en & reg::GYRO_X_FIFO_EN)
      for (int i = 6; i < 8; ++i) rec[n++] = out[i];
    if (en & reg::GYRO_Y_FIFO_EN)
      for (int i = 8; i < 10; ++i) rec[n++] = out[i];
    if (en & reg::GYRO_Z_FIFO_EN)
      for (int i = 10; i < 12; ++i) rec[n++] = out[i];
    if (en & reg::TEMP_FIFO_EN)
      for (int i = 12; i < 14; ++i) rec[n++] = out[i];
    s.to_fifo = true;
    const bool snapshot = (regs_[0][u8(Reg0::FIFO_MODE)] & 0x1F) != 0;
    if (fifo_size_ + n > fifo_.size()) {
      regs_[0][u8(Reg0::INT_STATUS_2)] |= reg::FIFO_OVERFLOW_INT;
      if (snapshot) {
        s.lost_on_chip = true;
      } else {
        while (fifo_size_ + n > fifo_.size()) fifo_pop();  // stream: the oldest bytes go
      }
    }
    if (!s.lost_on_chip) {
      for (std::size_t i = 0; i < n; ++i) fifo_push(rec[i]);
    }
  }
  regs_[0][u8(Reg0::INT_STATUS_1)] |= 0x01;
  samples_.push_back(s);

  // The magnetometer measures on its own 100 Hz clock; the aux master polls it at its ODR.
  if (ak_[u8(ak::Reg::CNTL2)] == ak::CONTINUOUS_100HZ) {
    if (t_ns >= next_mag_ns_) {
      next_mag_ns_ = t_ns + 10 * kNsPerMs;
      const Eigen::Vector3d m = truth.mag_body_uT;
      // AK09916 axes: Y and Z opposite to the body (accel) axes.
      mag_raw_ = {quantize(m.x() / ak::kUtPerLsb), quantize(-m.y() / ak::kUtPerLsb),
                  quantize(-m.z() / ak::kUtPerLsb)};
      for (int i = 0; i < 3; ++i) {
        ak_[u8(ak::Reg::HXL) + 2 * i] = static_cast<std::uint8_t>(mag_raw_[i] & 0xFF);
        ak_[u8(ak::Reg::HXL) + 2 * i + 1] =
            static_cast<std::uint8_t>(static_cast<std::uint16_t>(mag_raw_[i]) >> 8);
      }
      if (ak_[u8(ak::Reg::ST1)] & ak::DRDY) ak_[u8(ak::Reg::ST1)] |= ak::DOR;
      ak_[u8(ak::Reg::ST1)] |= ak::DRDY;
      ++mag_measurements_;
      mag_log_.push_back(mag_raw_);
    }
  }
  const DurationNs aux_period = static_cast<DurationNs>(
      1e9 / (1100.0 / (1 << (regs_[3][u8(Reg3::I2C_MST_ODR_CONFIG)] & 0x0F))));
  if (t_ns - last_aux_ns_ >= aux_period) {
    last_aux_ns_ = t_ns;
    aux_read();
  }
}

void Icm20948Sim::aux_read() {
  if ((regs_[0][u8(Reg0::USER_CTRL)] & reg::I2C_MST_EN) == 0) return;
  const std::uint8_t ctrl = regs_[3][u8(Reg3::I2C_SLV0_CTRL)];
  const std::uint8_t addr = regs_[3][u8(Reg3::I2C_SLV0_ADDR)];
  if ((ctrl & reg::I2C_SLV_EN) == 0 || (addr & reg::kI2cSlvRnw) == 0) return;
  if (!mag_present_ || (addr & 0x7F) != ak::kAddress) {
    regs_[0][u8(Reg0::I2C_MST_STATUS)] |= reg::I2C_SLV0_NACK;
    return;
  }
  const std::uint8_t start = regs_[3][u8(Reg3::I2C_SLV0_REG)];
  const int len = ctrl & reg::I2C_SLV_LENG_MASK;
  for (int i = 0; i < len; ++i) {
    const auto r = static_cast<std::uint8_t>(start + i);
    regs_[0][u8(Reg0::EXT_SLV_SENS_DATA_00) + i] = ak_[r & 0x3F];
    if (r == u8(ak::Reg::ST2)) ak_[u8(ak::Reg::ST1)] = 0;  // reading ST2 ends the data read
  }
}

void Icm20948Sim::slv4_transfer() {
  const std::uint8_t addr = regs_[3][u8(Reg3::I2C_SLV4_ADDR)];
  const std::uint8_t r = regs_[3][u8(Reg3::I2C_SLV4_REG)];
  regs_[3][u8(Reg3::I2C_SLV4_CTRL)] &= static_cast<std::uint8_t>(~reg::I2C_SLV_EN);
  if ((regs_[0][u8(Reg0::USER_CTRL)] & reg::I2C_MST_EN) == 0) return;  // never completes
  if (!mag_present_ || (addr & 0x7F) != ak::kAddress) {
    regs_[0][u8(Reg0::I2C_MST_STATUS)] |= reg::I2C_SLV4_NACK;
    return;
  }
  if (addr & reg::kI2cSlvRnw) {
    regs_[3][u8(Reg3::I2C_SLV4_DI)] = ak_[r & 0x3F];
  } else {
    ak_[r & 0x3F] = regs_[3][u8(Reg3::I2C_SLV4_DO)];
    if (r == u8(ak::Reg::CNTL2)) next_mag_ns_ = now_ns_ + 10 * kNsPerMs;
  }
  regs_[0][u8(Reg0::I2C_MST_STATUS)] |= reg::I2C_SLV4_DONE;
}

void Icm20948Sim::write_reg(std::uint8_t r, std::uint8_t v) {
  if (r == reg::kRegBankSel) {
    for (auto& b : regs_) b[r] = v & 0x30;
    return;
  }
  const int b = bank();
  if (b == 0 && r == u8(Reg0::PWR_MGMT_1) && (v & reg::DEVICE_RESET)) {
    ++device_resets_;
    const std::uint64_t k = k_;
    power_on_reset();
    k_ = k;
    nack_budget_ = nack_after_reset_;
    return;
  }
  if (b == 0 &&
      (r == u8(Reg0::WHO_AM_I) || r == u8(Reg0::FIFO_COUNTH) || r == u8(Reg0::FIFO_COUNTL))) {
    return;  // read-only
  }
  if (b == 0 && r == u8(Reg0::FIFO_R_W)) return;
  regs_[b][r] = v;
  if (b == 0 && r == u8(Reg0::PWR_MGMT_1) && awake() && !was_awake_) {
    next_sample_ns_ = now_ns_ + period_ns();  // the sample clock starts at wake-up
  }
  was_awake_ = awake();
  if (b == 0 && r == u8(Reg0::FIFO_RST) && (v & 0x1F) != 0) fifo_head_ = fifo_size_ = 0;
  if (b == 0 && r == u8(Reg0::USER_CTRL)) {
    regs_[0][r] &= static_cast<std::uint8_t>(~(reg::I2C_MST_RST | reg::SRAM_RST | reg::DMP_RST));
  }
  if (b == 3 && r == u8(Reg3::I2C_SLV4_CTRL) && (v & reg::I2C_SLV_EN)) slv4_transfer();
}

std::uint8_t Icm20948Sim::read_reg(std::uint8_t r) {
  const int b = bank();
  if (b == 0 && r == u8(Reg0::FIFO_R_W)) return fifo_pop();
  if (b == 0 && r == u8(Reg0::FIFO_COUNTH)) {
    return static_cast<std::uint8_t>((fifo_size_ >> 8) & reg::kFifoCountHMask);
  }
  if (b == 0 && r == u8(Reg0::FIFO_COUNTL)) return static_cast<std::uint8_t>(fifo_size_ & 0xFF);
  const std::uint8_t v = regs_[b][r & 0x7F];
  if (b == 0 && (r == u8(Reg0::INT_STATUS_1) || r == u8(Reg0::INT_STATUS_2) ||
                 r == u8(Reg0::I2C_MST_STATUS))) {
    regs_[b][r] = 0;  // clear on read
  }
  return v;
}

int Icm20948Sim::rdwr(i2c_rdwr_ioctl_data& data) {
  SimTraffic log;
  log.bank = static_cast<std::uint8_t>(bank());
  if (data.nmsgs >= 1) {
    log.addr = data.msgs[0].addr;
    if ((data.msgs[0].flags & I2C_M_RD) == 0 && data.msgs[0].len > 0) {
      log.reg = data.msgs[0].buf[0];
      log.write_len = data.msgs[0].len;
    }
    if (data.msgs[data.nmsgs - 1].flags & I2C_M_RD) log.read_len = data.msgs[data.nmsgs - 1].len;
  }
  const auto finish = [this, &log](int result) {
    log.result = result;
    if (logging_) traffic_.push_back(log);
    return result;
  };
  if (data.nmsgs == 0 || data.nmsgs > 2) return finish(-EINVAL);
  for (std::uint32_t i = 0; i < data.nmsgs; ++i) {
    if (data.msgs[i].addr != address_) return finish(-ENXIO);  // nobody answers there
  }
  if (log.read_len > max_read_bytes_) return finish(-EOPNOTSUPP);
  if (stuck_) return finish(-ETIMEDOUT);
  if (unplugged_) return finish(-ENXIO);
  if (nack_budget_ > 0) {
    --nack_budget_;
    return finish(-EREMOTEIO);
  }
  std::optional<Fault> fault;
  if (!faults_.empty()) {
    fault = faults_.front();
    faults_.pop_front();
  }
  if (fault == Fault::kNack) return finish(-ENXIO);
  if (fault == Fault::kEio) return finish(-EIO);  // before any byte: nothing changed
  if ((fault == Fault::kShortRead || fault == Fault::kEioMidRead) &&
      (data.msgs[data.nmsgs - 1].flags & I2C_M_RD) == 0) {
    faults_.push_front(*fault);  // a fault in a read needs a read: keep it for the next one
    fault.reset();
  }

  // A write message: register pointer then data bytes (auto-increment).
  std::uint8_t ptr = 0;
  const i2c_msg& first = data.msgs[0];
  std::uint32_t next = 0;
  if ((first.flags & I2C_M_RD) == 0) {
    if (first.len == 0) return finish(-EINVAL);
    ptr = first.buf[0];
    for (std::uint16_t i = 1; i < first.len; ++i)
      write_reg(static_cast<std::uint8_t>(ptr + i - 1), first.buf[i]);
    next = 1;
  }
  if (next < data.nmsgs) {
    i2c_msg& rd = data.msgs[next];
    if ((rd.flags & I2C_M_RD) == 0) return finish(-EINVAL);
    // A short read: the adapter stops after half the bytes (they are consumed on the chip).
    // The address pointer increments after each byte but stops at FIFO_R_W: a burst from
    // FIFO_COUNTH reads the count, then pops FIFO bytes.
    const auto fifo_r_w = u8(Reg0::FIFO_R_W);
    const bool fifo = bank() == 0 && ptr <= fifo_r_w && ptr + rd.len > fifo_r_w;
    if (fault == Fault::kEioMidRead && !fifo) {
      faults_.push_front(*fault);  // for the next FIFO burst
      fault.reset();
    }
    const bool half = fault == Fault::kShortRead || fault == Fault::kEioMidRead;
    const std::uint16_t len = half ? rd.len / 2 : rd.len;
    // FIFO_COUNTH latches the count for FIFO_COUNTL.
    for (std::uint16_t i = 0; i < len; ++i) {
      const auto r = static_cast<std::uint8_t>(ptr + i);
      rd.buf[i] = read_reg(fifo ? std::min(r, fifo_r_w) : r);
    }
    rd.len = len;
    if (fault == Fault::kEioMidRead) return finish(-EIO);  // the bytes are gone from the chip
  }
  return finish(static_cast<int>(data.nmsgs));
}

}  // namespace wallar::test
