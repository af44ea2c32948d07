// SPDX-License-Identifier: Apache-2.0
/// @file test_icm20948.cpp
/// @brief ICM-20948 driver: register map, byte reassembly and scaling against hand-computed
/// vectors, and the state machine on the register-level simulator, fault by fault.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "icm20948_sim.hpp"
#include "imu_rig.hpp"
#include "wallar/drivers/imu/icm20948.hpp"
#include "wallar/drivers/imu/icm20948_registers.hpp"
#include "wallar/firmware/live_imu.hpp"

namespace wallar::test {
namespace {

using drivers::Icm20948;
using drivers::ImuCounters;
using drivers::ImuDriverState;
namespace icm = drivers::icm20948;

// ---- Register map and helpers --------------------------------------------------------------

TEST(Icm20948Registers, AddressesAndBitsFromTheDatasheet) {
  EXPECT_EQ(icm::kWhoAmIValue, 0xEA);
  EXPECT_EQ(static_cast<int>(icm::Reg0::PWR_MGMT_1), 0x06);
  EXPECT_EQ(static_cast<int>(icm::Reg0::FIFO_COUNTH), 0x70);
  EXPECT_EQ(static_cast<int>(icm::Reg0::FIFO_R_W), 0x72);
  EXPECT_EQ(static_cast<int>(icm::Reg2::ACCEL_CONFIG), 0x14);
  EXPECT_EQ(static_cast<int>(icm::Reg3::I2C_SLV0_CTRL), 0x05);
  EXPECT_EQ(icm::bank_sel_value(icm::Bank::k0), 0x00);
  EXPECT_EQ(icm::bank_sel_value(icm::Bank::k2), 0x20);
  EXPECT_EQ(icm::bank_sel_value(icm::Bank::k3), 0x30);
  EXPECT_EQ(icm::gyro_fs_sel(3), 0x06);
  EXPECT_EQ(icm::gyro_dlpfcfg(1), 0x08);
  EXPECT_EQ(icm::accel_fs_sel(3) | icm::accel_dlpfcfg(7), 0x3E);
  EXPECT_EQ(sizeof(icm::FifoRecord), 12u);
  EXPECT_EQ(icm::kFifoMaxRecords, 42u);
}

TEST(Icm20948Scaling, BigAndLittleEndianReassembly) {
  EXPECT_EQ(icm::be16(0x12, 0x34), 0x1234);
  EXPECT_EQ(icm::be16(0xFF, 0xFE), -2);
  EXPECT_EQ(icm::be16(0x80, 0x00), -32768);
  EXPECT_EQ(icm::be16(0x7F, 0xFF), 32767);
  EXPECT_EQ(icm::le16(0x34, 0x12), 0x1234);
  EXPECT_EQ(icm::le16(0x00, 0x80), -32768);
}

TEST(Icm20948Scaling, FifoRecordToSiUnits) {
  // accel x = 2048 (1 g at ±16 g), y = -4096 (-2 g), z = 0x0001; gyro x = 164 (10 dps at
  // ±2000 dps), y = -1640 (-100 dps), z = 0.
  const std::array<std::uint8_t, 12> bytes{0x08, 0x00, 0xF0, 0x00, 0x00, 0x01,
                                           0x00, 0xA4, 0xF9, 0x98, 0x00, 0x00};
  icm::FifoRecord r;
  std::memcpy(&r, bytes.data(), sizeof r);
  const auto s = icm::scale_record(r, icm::AccelRange::k16g, icm::GyroRange::k2000dps);
  EXPECT_DOUBLE_EQ(s.accel_m_s2.x(), 9.80665);
  EXPECT_DOUBLE_EQ(s.accel_m_s2.y(), -2.0 * 9.80665);
  EXPECT_DOUBLE_EQ(s.accel_m_s2.z(), 9.80665 / 2048.0);
  EXPECT_NEAR(s.gyro_rad_s.x(), 10.0 * M_PI / 180.0, 1e-12);
  EXPECT_NEAR(s.gyro_rad_s.y(), -100.0 * M_PI / 180.0, 1e-12);
  EXPECT_EQ(s.gyro_rad_s.z(), 0.0);
  // The same bytes at ±2 g / ±250 dps.
  const auto s2 = icm::scale_record(r, icm::AccelRange::k2g, icm::GyroRange::k250dps);
  EXPECT_DOUBLE_EQ(s2.accel_m_s2.x(), 2048.0 / 16384.0 * 9.80665);
  EXPECT_NEAR(s2.gyro_rad_s.x(), 164.0 / 131.0 * M_PI / 180.0, 1e-12);
  EXPECT_DOUBLE_EQ(icm::accel_lsb_per_g(icm::AccelRange::k16g), 2048.0);
  EXPECT_DOUBLE_EQ(icm::gyro_lsb_per_dps(icm::GyroRange::k2000dps), 16.4);
}

TEST(Icm20948Scaling, Temperature) {
  EXPECT_DOUBLE_EQ(icm::temperature_c(21), 21.0);
  EXPECT_NEAR(icm::temperature_c(3360), 21.0 + 3339.0 / 333.87, 1e-12);  // 31.0009 degC
  EXPECT_NEAR(icm::temperature_c(-3318), 21.0 - 3339.0 / 333.87, 1e-12);
}

TEST(Icm20948Scaling, Ak09916BurstToBodyFrame) {
  // ST1 = DRDY; HX = 100 (15 uT), HY = -100 (-15 uT), HZ = 256 (38.4 uT); TMPS; ST2 = 0.
  std::array<std::uint8_t, 9> b{0x01, 0x64, 0x00, 0x9C, 0xFF, 0x00, 0x01, 0x00, 0x00};
  const auto m = icm::ak09916_body_uT(b);
  ASSERT_TRUE(m);
  EXPECT_NEAR(m->x(), 15.0, 1e-12);
  EXPECT_NEAR(m->y(), 15.0, 1e-12);   // AK Y is opposite to body Y
  EXPECT_NEAR(m->z(), -38.4, 1e-12);  // AK Z is opposite to body Z
  b[0] = 0x00;                        // no new data
  EXPECT_FALSE(icm::ak09916_body_uT(b));
  b[0] = 0x01;
  b[8] = icm::ak09916::HOFL;  // overflow: invalid
  EXPECT_FALSE(icm::ak09916_body_uT(b));
}

TEST(Icm20948Scaling, RateDivider) {
  EXPECT_EQ(icm::rate_divider(1000.0), 0);  // 1125 Hz is the nearest
  EXPECT_EQ(icm::rate_divider(1125.0), 0);
  EXPECT_EQ(icm::rate_divider(500.0), 1);   // 562.5 Hz
  EXPECT_EQ(icm::rate_divider(100.0), 10);  // 102.3 Hz
  EXPECT_EQ(icm::rate_divider(1.0), 255);
  EXPECT_EQ(icm::rate_divider(-5.0), 0);
  EXPECT_DOUBLE_EQ(icm::rate_of_divider(1), 562.5);
}

TEST(Icm20948SelfTest, RatioAgainstFactoryTrim) {
  EXPECT_DOUBLE_EQ(icm::self_test_factory_response(1), 2620.0);
  EXPECT_NEAR(icm::self_test_factory_response(101), 2620.0 * std::pow(1.01, 100), 1e-9);
  const std::array<std::uint8_t, 3> otp{1, 1, 1};
  const std::array<double, 3> off{10.0, -20.0, 16384.0};
  const std::array<double, 3> good{10.0 + 2620.0, -20.0 + 2000.0, 16384.0 + 3500.0};
  auto r = icm::evaluate_self_test(off, good, otp, off, good, otp);
  EXPECT_TRUE(r.pass());
  EXPECT_NEAR(r.gyro_ratio[0], 1.0, 1e-12);
  EXPECT_NEAR(r.accel_ratio[2], 3500.0 / 2620.0, 1e-12);
  // A dead axis (no response) fails; a missing trim code fails.
  std::array<double, 3> dead = good;
  dead[1] = off[1];
  r = icm::evaluate_self_test(off, dead, otp, off, good, otp);
  EXPECT_FALSE(r.gyro_pass);
  EXPECT_TRUE(r.accel_pass);
  r = icm::evaluate_self_test(off, good, otp, off, good, {1, 0, 1});
  EXPECT_FALSE(r.accel_pass);
}

TEST(Icm20948SelfTest, RunOnTheSimulatedChip) {
  for (const double gain : {1.0, 0.2}) {
    Icm20948Sim sim;  // at rest: gravity on z
    drivers::I2cBus bus(sim, 0x68);
    const auto wait = [&sim](DurationNs d) { sim.advance_to(sim.now() + d); };
    const auto r = [&] {
      sim.set_self_test_gain(gain);
      return icm::run_self_test(bus, wait);
    }();
    ASSERT_TRUE(r);
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(r->gyro_ratio[a], gain, 0.01) << a;
      EXPECT_NEAR(r->accel_ratio[a], gain, 0.01) << a;
    }
    EXPECT_EQ(r->pass(), gain == 1.0);
    // Self-test is switched off again.
    EXPECT_EQ(sim.peek(2, static_cast<std::uint8_t>(icm::Reg2::GYRO_CONFIG_2)), 0);
    EXPECT_EQ(sim.peek(2, static_cast<std::uint8_t>(icm::Reg2::ACCEL_CONFIG_2)), 0);
  }
  Icm20948Sim absent;
  absent.set_unplugged(true);
  drivers::I2cBus bus(absent, 0x68);
  EXPECT_FALSE(icm::run_self_test(bus, [](DurationNs) {}));
}

// ---- The driver on the simulator -----------------------------------------------------------

// Deterministic motion within the ±16 g / ±2000 dps ranges.
SimTruth motion(std::uint64_t, TimeNs t_ns) {
  const double t = ns_to_s(t_ns);
  SimTruth s;
  s.accel_m_s2 =
      Eigen::Vector3d(1.5 * std::sin(2 * M_PI * 0.7 * t), 2.0 * std::cos(2 * M_PI * 1.1 * t),
                      9.80665 + 0.5 * std::sin(2 * M_PI * 3.0 * t));
  s.gyro_rad_s =
      Eigen::Vector3d(0.8 * std::sin(2 * M_PI * 0.5 * t), -1.2 * std::cos(2 * M_PI * 0.9 * t),
                      0.3 * std::sin(2 * M_PI * 2.0 * t));
  s.mag_body_uT = Eigen::Vector3d(20.0 + 30.0 * std::sin(2 * M_PI * 1.0 * t), -5.0,
                                  -40.0 + 20.0 * std::cos(2 * M_PI * 0.7 * t));
  return s;
}

constexpr double kAccelLsb = 9.80665 / 2048.0;
constexpr double kGyroLsb = M_PI / 180.0 / 16.4;

// Every sample the driver put out since it last entered RUN is one the chip made, in order,
// with its exact raw values and its edge time; the chip's samples are all accounted for as
// put out or counted dropped.
void expect_stream_matches_chip(const ImuRig& rig, DurationNs time_tol_ns = 1000,
                                std::size_t warmup = 0, DurationNs warmup_tol_ns = 0) {
  const auto& out = rig.sink.samples;
  std::vector<const SimSample*> made;
  for (const auto& s : rig.sim.samples()) {
    if (s.to_fifo && !s.lost_on_chip && s.t_ns > rig.t_run) made.push_back(&s);
  }
  const DurationNs half_period = rig.driver.period_ns() / 2;
  std::size_t j = 0;
  for (std::size_t i = rig.samples_at_run; i < out.size(); ++i) {
    const ImuSample& o = out[i];
    // The chip sample nearest in time (samples lost in between are skipped, never reused).
    while (j < made.size() && made[j]->t_ns < o.t_ns - half_period) ++j;
    ASSERT_LT(j, made.size()) << "output sample " << i << " at " << o.t_ns
                              << " ns matches no chip sample (invented or misplaced)";
    const SimSample& m = *made[j];
    const DurationNs tol = i - rig.samples_at_run < warmup ? warmup_tol_ns : time_tol_ns;
    ASSERT_LE(std::llabs(m.t_ns - o.t_ns), tol) << "sample " << i << " (chip k=" << m.k << ")";
    for (int a = 0; a < 3; ++a) {
      ASSERT_DOUBLE_EQ(o.accel_m_s2[a], m.accel[a] * kAccelLsb) << "sample " << i;
      ASSERT_NEAR(o.gyro_rad_s[a], m.gyro[a] * kGyroLsb, 1e-12) << "sample " << i;
    }
    const SimTruth truth = motion(m.k, m.t_ns);
    EXPECT_LE((o.accel_m_s2 - truth.accel_m_s2).cwiseAbs().maxCoeff(), 0.5 * kAccelLsb + 1e-12);
    EXPECT_LE((o.gyro_rad_s - truth.gyro_rad_s).cwiseAbs().maxCoeff(), 0.5 * kGyroLsb + 1e-12);
    EXPECT_GE(o.publish_t_ns, o.t_ns);
    if (i > rig.samples_at_run) {
      ASSERT_GT(o.t_ns, out[i - 1].t_ns) << "timestamps must increase";
    }
    ++j;
  }
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ((c.samples - rig.counters_at_run.samples) +
                (c.dropped_samples - rig.counters_at_run.dropped_samples),
            rig.generated_since_run())
      << drivers::format_counters(c);
}

TEST(Icm20948Driver, StreamsTheTruthStampedAtTheEdges) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(50 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_TRUE(rig.driver.mag_ok());
  EXPECT_DOUBLE_EQ(rig.driver.rate_hz(), 1125.0);
  rig.run_until(1050 * kNsPerMs);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_GT(c.samples, 1100u);
  EXPECT_EQ(c.samples, rig.sink.samples.size());
  EXPECT_EQ(c.bad_transfer + c.nack + c.short_transfer + c.fifo_overflow + c.dropped_samples +
                c.missed_data_ready + c.config_mismatch + c.resets + c.probe_failures,
            0u)
      << drivers::format_counters(c);
  expect_stream_matches_chip(rig);
  // Magnetometer at ~100 Hz: each reading one the AK09916 made, in order, in the body frame.
  const auto& mags = rig.sim.mag_log();
  std::size_t m = 0;
  int attached = 0;
  for (const auto& s : rig.sink.samples) {
    if (!s.mag_uT) continue;
    ++attached;
    const Eigen::Vector3d body = *s.mag_uT;
    while (m < mags.size() && !(std::abs(mags[m][0] * 0.15 - body.x()) < 1e-9 &&
                                std::abs(-mags[m][1] * 0.15 - body.y()) < 1e-9 &&
                                std::abs(-mags[m][2] * 0.15 - body.z()) < 1e-9)) {
      ++m;
    }
    ASSERT_LT(m, mags.size()) << "mag reading " << body.transpose() << " the chip never made";
  }
  EXPECT_GE(attached, static_cast<int>(mags.size()) * 9 / 10);
  EXPECT_GE(attached, 90);
  // Each edge's record comes with the count in one combined transaction in bank 0 (from
  // FIFO_COUNTH on into FIFO_R_W), whole records only; nothing else reads the FIFO, and the
  // clear-on-read status is not read per sample.
  int bursts = 0;
  for (const auto& t : rig.sim.traffic()) {
    if (t.bank != 0 || t.read_len == 0) continue;
    EXPECT_NE(t.reg, static_cast<std::uint8_t>(icm::Reg0::FIFO_R_W));
    if (t.reg == static_cast<std::uint8_t>(icm::Reg0::FIFO_COUNTH)) {
      ++bursts;
      EXPECT_EQ(t.write_len, 1);
      EXPECT_EQ(t.read_len, 2 + 12);
    }
  }
  EXPECT_GT(bursts, 1000);
  EXPECT_LE(static_cast<std::uint64_t>(bursts), c.samples);
}

TEST(Icm20948Driver, BatchedReadsBackDateOlderRecordsByThePeriod) {
  Icm20948::Config config;
  config.fifo_read_every = 5;
  ImuRig rig(config, motion);
  rig.run_until(1000 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_EQ(rig.driver.counters().dropped_samples, 0u);
  // Only every fifth edge is paired with a record; the four older ones are back-dated.
  expect_stream_matches_chip(rig, 1000);
}

TEST(Icm20948Driver, OnAnSmbusOnlyBusFifoBurstsAreSplitIntoWholeRecords) {
  Icm20948::Config config;
  config.fifo_read_every = 5;  // 60-byte bursts, more than an SMBus block's 32
  ImuRig rig(config, motion);
  rig.sim.set_max_read_bytes(drivers::kSmbusBlockMax);
  rig.run_until(1000 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(c.bad_transfer, 0u);
  EXPECT_EQ(c.resync, 0u);
  EXPECT_EQ(c.dropped_samples, 0u);
  EXPECT_GT(c.samples, 1000u);
  expect_stream_matches_chip(rig, 1000);
  int fifo_reads = 0;
  for (const auto& t : rig.sim.traffic()) {
    if (t.bank == 0 && t.reg == static_cast<std::uint8_t>(icm::Reg0::FIFO_R_W) && t.read_len) {
      ++fifo_reads;
      EXPECT_LE(t.read_len, 24);  // two whole records
      EXPECT_EQ(t.read_len % 12, 0);
      EXPECT_EQ(t.result, 2);
    }
  }
  EXPECT_GT(fifo_reads, 2 * 1000 / 5);
}

TEST(Icm20948Driver, SlowOscillatorIsFollowedByTheDeviceClock) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.sim.set_rate_error(0.01);  // the chip's oscillator runs 1 % slow
  rig.run_until(3000 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  // DeviceClock carries the nominal period (1 % off) until its slope has 16 samples of
  // baseline: 100 us at first, then the edges' own precision.
  expect_stream_matches_chip(rig, 1000, 64, 100000);
}

TEST(Icm20948Driver, ProbeRetriesWhileTheChipNacksAfterReset) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.sim.set_nack_after_reset(3);
  rig.run_until(200 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(c.nack, 3u);  // NACKs are not retried by the bus: each one is seen
  EXPECT_GE(c.probe_failures, 1u);
  EXPECT_EQ(c.resets, 0u);
  EXPECT_GT(c.samples, 100u);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, NackWhileRunningIsCountedAndTheStreamGoesOn) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  const auto bus_before = rig.bus.counters();
  rig.sim.inject(Icm20948Sim::Fault::kNack, 1);
  rig.run_until(300 * kNsPerMs);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(c.nack, 1u);
  EXPECT_EQ(rig.bus.counters().retries, bus_before.retries);  // a NACK is not retried
  EXPECT_EQ(c.resets, 0u);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_GT(c.samples, 300u);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, EioIsRetriedOnlyWhereTheReadCanBeRepeatedAndCountedByTheDriver) {
  // Each read is one burst from FIFO_COUNTH into FIFO_R_W: a bus error there is never retried
  // (FIFO bytes may have left the chip), it is counted and the FIFO is started over; the
  // failure leaves the bank unknown, so emptying the FIFO starts with a bank select, a write
  // the bus does retry.
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  const std::uint64_t resync_before = rig.driver.counters().resync;
  rig.sim.inject(Icm20948Sim::Fault::kEio, 2);  // the burst, then the bank select
  rig.run_until(200 * kNsPerMs);
  EXPECT_EQ(rig.driver.counters().bad_transfer, 1u);
  EXPECT_EQ(rig.driver.counters().resync, resync_before + 1);
  EXPECT_EQ(rig.bus.counters().retries, 1u);
  rig.sim.inject(Icm20948Sim::Fault::kEio, 3);  // burst, bank select, and its first retry
  rig.run_until(400 * kNsPerMs);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(c.bad_transfer, 2u);
  EXPECT_EQ(c.resync, resync_before + 2);
  EXPECT_EQ(rig.bus.counters().retries, 3u);
  EXPECT_EQ(c.resets, 0u);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kRun);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, AFifoBurstThatFailsPartWayIsResynchronisedNotRetried) {
  // A bus error half-way through a FIFO_R_W burst: the bytes clocked out before it are gone
  // from the chip. Retried, the burst would read the bytes after them and push records cut at
  // the wrong boundaries; the driver must count it, empty the FIFO and start over.
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  const std::uint64_t resync_before = rig.driver.counters().resync;
  const std::uint64_t once_before = rig.bus.counters().once;
  rig.sim.inject(Icm20948Sim::Fault::kEioMidRead, 1);
  rig.run_until(400 * kNsPerMs);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(rig.bus.counters().retries, 0u);
  EXPECT_GT(rig.bus.counters().once, once_before);  // FIFO bursts go once
  EXPECT_EQ(c.bad_transfer, 1u);
  EXPECT_EQ(c.resync, resync_before + 1);
  EXPECT_GT(c.dropped_samples, 0u);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kRun);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, ShortTransferIsCountedAndNoPartialRecordIsPushed) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  for (int i = 0; i < 5; ++i) {
    rig.sim.inject(Icm20948Sim::Fault::kShortRead, 1);
    rig.run_until(rig.now + 20 * kNsPerMs);
  }
  rig.run_until(rig.now + 100 * kNsPerMs);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(c.short_transfer, 5u);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kRun);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, StuckBusRecoversThroughTheHookAndAFullReset) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  rig.sim.set_stuck(true);
  rig.run_until(300 * kNsPerMs);
  EXPECT_NE(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_GE(rig.recoveries, 1);
  EXPECT_EQ(rig.bus.counters().recoveries, static_cast<std::uint64_t>(rig.recoveries));
  EXPECT_GE(rig.driver.counters().resets, 1u);
  EXPECT_GT(rig.driver.counters().bad_transfer, 10u);
  rig.sim.set_stuck(false);  // what the recovery would achieve on a real bus
  rig.run_until(500 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_GT(rig.t_run, 300 * kNsPerMs);
  EXPECT_EQ(rig.driver.counters().resets, 1u);
  EXPECT_GT(rig.sink.samples.size(), rig.samples_at_run + 100);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, FifoOverflowIsFlushedCountedAndNothingIsInvented) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  const TimeNs t_last_read = rig.sink.samples.back().t_ns;
  rig.stall_until = 200 * kNsPerMs;  // the imu thread sleeps for 100 ms: 112 samples
  rig.run_until(400 * kNsPerMs);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(c.fifo_overflow, 1u);
  EXPECT_EQ(c.resets, 0u);
  // Everything the chip made after the last sample read, up to the edge that found the
  // overflow, is counted dropped.
  const std::uint64_t made_in_gap =
      rig.sim.fifo_samples_between(t_last_read, 200 * kNsPerMs + 1 * kNsPerMs);
  EXPECT_NEAR(static_cast<double>(c.dropped_samples), static_cast<double>(made_in_gap), 1.0);
  EXPECT_GT(c.dropped_samples, 100u);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_GT(rig.sink.samples.back().t_ns, 390 * kNsPerMs);  // the stream continued
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, DataReadyThatStopsFallsBackToPolling) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  ASSERT_FALSE(rig.driver.polling());
  rig.edges = false;  // the INT wire breaks
  rig.run_until(300 * kNsPerMs);
  EXPECT_TRUE(rig.driver.polling());
  const ImuCounters c1 = rig.driver.counters();
  // Every sample read without its edge is a missed data-ready (a few may wait in the FIFO).
  const std::uint64_t without_edge = rig.sim.fifo_samples_between(100 * kNsPerMs, 300 * kNsPerMs);
  EXPECT_LE(c1.missed_data_ready, without_edge);
  EXPECT_GE(c1.missed_data_ready + 3, without_edge);
  EXPECT_EQ(c1.dropped_samples, 0u);
  rig.edges = true;
  rig.run_until(500 * kNsPerMs);
  EXPECT_FALSE(rig.driver.polling());
  EXPECT_EQ(rig.driver.counters().missed_data_ready, c1.missed_data_ready);
  EXPECT_EQ(rig.driver.counters().resets, 0u);
  // While polling the read time is the observation: stamps stay within a period of the truth.
  expect_stream_matches_chip(rig, rig.driver.period_ns());
}

TEST(Icm20948Driver, UnpluggedAndBackGoesThroughResetAndStreamsAgain) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  rig.sim.set_unplugged(true);
  rig.run_until(400 * kNsPerMs);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kReset);
  EXPECT_GT(rig.driver.counters().nack, 10u);
  EXPECT_EQ(rig.driver.counters().resets, 1u);
  rig.sim.set_unplugged(false);
  rig.run_until(700 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_GT(rig.t_run, 400 * kNsPerMs);
  EXPECT_EQ(rig.driver.counters().resets, 1u);
  EXPECT_GE(rig.sim.device_resets(), 2);
  EXPECT_GT(rig.sink.samples.size(), rig.samples_at_run + 200);
  EXPECT_TRUE(rig.driver.mag_ok());
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, ConfigChangedBehindItsBackResets) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  rig.sim.poke(2, static_cast<std::uint8_t>(icm::Reg2::GYRO_CONFIG_1), 0x01);  // ±250 dps
  rig.run_until(300 * kNsPerMs);
  const ImuCounters& c = rig.driver.counters();
  EXPECT_EQ(c.config_mismatch, 1u);
  EXPECT_EQ(c.resets, 1u);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_EQ(rig.sim.peek(2, static_cast<std::uint8_t>(icm::Reg2::GYRO_CONFIG_1)) & 0x06, 0x06);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, StreamsWithoutAMagnetometer) {
  ImuRig rig(Icm20948::Config{}, motion);
  rig.sim.set_mag_present(false);
  rig.run_until(300 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_FALSE(rig.driver.mag_ok());
  EXPECT_EQ(rig.driver.mag_probe_failures(), 1u);
  for (const auto& s : rig.sink.samples) EXPECT_FALSE(s.mag_uT);
  expect_stream_matches_chip(rig);
}

TEST(Icm20948Driver, WithoutAnInterruptLineItPollsAndCountsNoMissedEdges) {
  Icm20948::Config config;
  config.has_data_ready = false;
  config.fifo_read_every = 4;
  config.mag_enabled = false;
  ImuRig rig(config, motion);
  rig.edges = false;
  rig.run_until(500 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_TRUE(rig.driver.polling());
  EXPECT_EQ(rig.driver.counters().missed_data_ready, 0u);
  EXPECT_GT(rig.driver.counters().samples, 400u);
  expect_stream_matches_chip(rig, rig.driver.period_ns());
}

TEST(Icm20948Driver, AnEdgeWithoutItsRecordIsNotTrustedTheFifoIsStartedOver) {
  // A burst reads the records the edges announced: an edge whose record is not in the FIFO
  // (a stale edge) makes it read past the FIFO's end, where a record the chip writes during
  // the burst would be cut. The count says so; nothing read past it is pushed.
  ImuRig rig(Icm20948::Config{}, motion);
  rig.run_until(100 * kNsPerMs);
  ASSERT_EQ(rig.driver.state(), ImuDriverState::kRun);
  const std::uint64_t resync_before = rig.driver.counters().resync;
  const std::uint64_t samples_before = rig.driver.counters().samples;
  rig.driver.step(rig.now, rig.now);  // an edge the chip never raised: the FIFO is empty
  EXPECT_EQ(rig.driver.counters().resync, resync_before + 1);
  EXPECT_EQ(rig.driver.counters().samples, samples_before);
  rig.run_until(300 * kNsPerMs);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kRun);
  EXPECT_GT(rig.driver.counters().samples, samples_before + 200);
  expect_stream_matches_chip(rig);
}

// Bus cost per sample in steady state, from the simulator's traffic log: transactions, and
// the time they hold a 400 kHz bus (START, address and register bytes with their ACKs, a
// repeated START and address for a read, the data bytes, STOP: 9 bit times per byte).
struct BusCost {
  double transactions_per_sample = 0.0;
  double bus_us_per_sample = 0.0;
  double bus_load = 0.0;  // fraction of the bus's time
};
BusCost measure_bus_cost(unsigned fifo_read_every, bool mag) {
  Icm20948::Config config;
  config.fifo_read_every = fifo_read_every;
  config.mag_enabled = mag;
  ImuRig rig(config, motion);
  rig.run_until(200 * kNsPerMs);
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kRun);
  rig.sim.clear_traffic();
  const std::uint64_t samples_before = rig.driver.counters().samples;
  rig.run_until(1200 * kNsPerMs);
  const double samples = static_cast<double>(rig.driver.counters().samples - samples_before);
  double bits = 0.0;
  for (const SimTraffic& t : rig.sim.traffic()) {
    bits += 1.0 + 9.0 * (1 + t.write_len) + 1.0;
    if (t.read_len > 0) bits += 1.0 + 9.0 * (1 + t.read_len);
  }
  constexpr double kBitUs = 1e6 / 400e3;
  BusCost c;
  c.transactions_per_sample = static_cast<double>(rig.sim.traffic().size()) / samples;
  c.bus_us_per_sample = bits * kBitUs / samples;
  c.bus_load = bits * kBitUs / 1e6;  // over one second of streaming
  EXPECT_EQ(rig.driver.counters().dropped_samples, 0u);
  expect_stream_matches_chip(rig);
  return c;
}

TEST(Icm20948Driver, BusCostPerSampleFromTheSimulatorsCounters) {
  // docs/perf.md "IMU bus cost per sample" quotes these lines.
  // Before the count and the records shared one burst (INT_STATUS_2, FIFO_COUNT and FIFO_R_W
  // each a transaction, a register re-checked and the magnetometer polled per read), one
  // sample a read took 5.4 transactions and 833 us of the bus: 94 % of it at 1125 Hz.
  for (const unsigned every : {1U, 4U}) {
    for (const bool mag : {true, false}) {
      const BusCost c = measure_bus_cost(every, mag);
      EXPECT_LT(c.transactions_per_sample, every == 1 ? 1.4 : 0.6);
      // The floor is the record itself: 12 bytes of 9 bit times, 270 us.
      EXPECT_LT(c.bus_us_per_sample, every == 1 ? 460.0 : 360.0);
      std::printf(
          "icm20948 bus: fifo_read_every=%u mag=%d: %.3f transactions/sample, "
          "%.1f us/sample at 400 kHz, bus load %.1f %%\n",
          every, mag ? 1 : 0, c.transactions_per_sample, c.bus_us_per_sample, 100.0 * c.bus_load);
    }
  }
}

// The imu thread's start-up check (firmware::StartupRate) on the driver: the nominal rate
// from a healthy chip; well under it when the thread keeps stalling and the FIFO overflows;
// nothing at all from a chip that never answers.
double startup_rate(ImuRig& rig, DurationNs stall_every_ns) {
  firmware::StartupRate rate(firmware::LiveImu::kRateWindowNs);
  for (TimeNs t = 0; t <= 5 * kNsPerS; t += kNsPerMs) {
    if (stall_every_ns > 0 && t % stall_every_ns == 0 && t > 0) rig.stall_until = t + 60 * kNsPerMs;
    rig.run_until(t);
    if (const auto hz = rate.update(t, rig.driver.counters().samples)) return *hz;
  }
  ADD_FAILURE() << "no rate after 5 s";
  return -1.0;
}

TEST(Icm20948Driver, TheStartupRateCheckSeesAChipThatLosesSamples) {
  ImuRig healthy(Icm20948::Config{}, motion);
  const double hz = startup_rate(healthy, 0);
  EXPECT_NEAR(hz, healthy.driver.rate_hz(), 3.0);
  EXPECT_TRUE(firmware::rate_ok(hz, healthy.driver.rate_hz()));
  ImuRig stalling(Icm20948::Config{}, motion);
  const double lossy = startup_rate(stalling, 100 * kNsPerMs);  // 60 ms of every 100 asleep
  EXPECT_GT(stalling.driver.counters().fifo_overflow, 10u);
  EXPECT_FALSE(firmware::rate_ok(lossy, stalling.driver.rate_hz())) << lossy;
  EXPECT_GT(lossy, 0.0);
  ImuRig dead(Icm20948::Config{}, motion);
  dead.sim.set_unplugged(true);
  EXPECT_EQ(startup_rate(dead, 0), 0.0);
  EXPECT_FALSE(firmware::rate_ok(0.0, dead.driver.rate_hz()));
}

// What the check says: each warning one line naming the device and the board's key, the same
// through the log ring (the appliance's SCHED_FIFO imu thread) as formatted on the spot.
TEST(Icm20948Driver, TheStartupRateLinesNameTheDeviceAndTheKey) {
  const auto lines = [](double measured_hz, firmware::LogRing* ring) {
    std::vector<std::string> out;
    std::string device = "/dev/i2c-1";
    firmware::say_imu_rate(3.0, measured_hz, 1125.0, device.c_str(), "running", ring,
                           [&](const std::string& l) { out.push_back(l); });
    device = "overwritten";  // a record keeps its own copy
    firmware::LogRecord r;
    while (ring != nullptr && ring->pop(r)) out.push_back(firmware::format_log_record(r));
    return out;
  };
  const std::vector<std::string> ok = lines(1120.0, nullptr);
  ASSERT_EQ(ok.size(), 1u);
  EXPECT_EQ(ok[0], "imu rate over 3 s: 1120.0 Hz (nominal 1125 Hz)");
  const std::vector<std::string> lossy = lines(560.0, nullptr);
  ASSERT_EQ(lossy.size(), 2u);
  EXPECT_EQ(lossy[1].substr(0, 92),
            "WARNING: imu (/dev/i2c-1): it delivers 560.0 Hz, not the 1125 Hz it runs at for "
            "imu.rate_hz:");
  const std::vector<std::string> none = lines(0.0, nullptr);
  ASSERT_EQ(none.size(), 1u);
  EXPECT_EQ(none[0],
            "WARNING: imu (/dev/i2c-1): no sample in its first 3 s (driver state running): check "
            "its wiring and the board's imu section (imu.driver, imu.bus, imu.address)");
  firmware::LogRing ring(8);
  EXPECT_EQ(lines(560.0, &ring), lossy);
  EXPECT_EQ(lines(0.0, &ring), none);
}

TEST(Icm20948Driver, NothingHappensBeforeTheFirstStepAndCountersPrint) {
  ImuRig rig(Icm20948::Config{}, motion);
  EXPECT_TRUE(rig.sim.traffic().empty());
  EXPECT_EQ(rig.driver.state(), ImuDriverState::kReset);
  EXPECT_EQ(rig.driver.name(), "icm20948");
  rig.run_until(20 * kNsPerMs);
  EXPECT_NE(drivers::format_counters(rig.driver.counters()).find("samples="), std::string::npos);
}

}  // namespace
}  // namespace wallar::test
