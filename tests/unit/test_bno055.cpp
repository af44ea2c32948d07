// SPDX-License-Identifier: Apache-2.0
/// @file test_bno055.cpp
/// @brief BNO055 UART: framing and scaling against hand-computed vectors, and the driver
/// against the pty simulator with every fault it must survive (each asserting recovery and
/// the counters).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <numbers>

#include "bno055_rig.hpp"
#include "wallar/core/error.hpp"
#include "wallar/drivers/imu/bno055_protocol.hpp"

namespace wallar::drivers {
namespace {

using bno055::Reg;
using bno055::ResponseKind;
using bno055::RxRing;
using bno055::UartStatus;
using test::Bno055Rig;
using test::burst_index;
using ::testing::HasSubstr;

constexpr double kPi = std::numbers::pi;

// ---- protocol: hand-computed vectors -------------------------------------------------------

TEST(Bno055Protocol, EncodesReadAndWriteRequests) {
  std::array<std::uint8_t, 4> rd{};
  EXPECT_EQ(bno055::encode_read(rd, Reg::kAccDataXLsb, 45), 4u);
  EXPECT_EQ(rd, (std::array<std::uint8_t, 4>{0xAA, 0x01, 0x08, 0x2D}));
  EXPECT_EQ(bno055::encode_read(rd, Reg::kChipId, 0), 0u);
  EXPECT_EQ(bno055::encode_read(rd, Reg::kChipId, 129), 0u);

  std::array<std::uint8_t, 8> wr{};
  const std::array<std::uint8_t, 1> ndof{0x0C};
  EXPECT_EQ(bno055::encode_write(wr, Reg::kOprMode, ndof), 5u);
  EXPECT_EQ((std::array<std::uint8_t, 5>{wr[0], wr[1], wr[2], wr[3], wr[4]}),
            (std::array<std::uint8_t, 5>{0xAA, 0x00, 0x3D, 0x01, 0x0C}));
  std::array<std::uint8_t, 4> tiny{};
  EXPECT_EQ(bno055::encode_write(tiny, Reg::kOprMode, ndof), 0u);  // does not fit
}

TEST(Bno055Protocol, LittleEndianInt16) {
  const std::array<std::uint8_t, 2> a{0x34, 0x12}, b{0xFF, 0xFF}, c{0x00, 0x80}, d{0xFF, 0x7F};
  EXPECT_EQ(bno055::le_i16(a.data()), 0x1234);
  EXPECT_EQ(bno055::le_i16(b.data()), -1);
  EXPECT_EQ(bno055::le_i16(c.data()), -32768);
  EXPECT_EQ(bno055::le_i16(d.data()), 32767);
}

TEST(Bno055Protocol, UnpacksAndScalesABurst) {
  std::array<std::uint8_t, bno055::kBurstBytes> bytes{};
  // ACC 0x08: x = 100 (1 m/s^2), y = -981 (0xFC2B), z = 0x0100 = 256
  bytes[0x00] = 0x64;
  bytes[0x01] = 0x00;
  bytes[0x02] = 0x2B;
  bytes[0x03] = 0xFC;
  bytes[0x04] = 0x00;
  bytes[0x05] = 0x01;
  // MAG 0x0E: x = 16 (1 uT), y = -32 (0xFFE0), z = 0
  bytes[0x06] = 0x10;
  bytes[0x07] = 0x00;
  bytes[0x08] = 0xE0;
  bytes[0x09] = 0xFF;
  // GYR 0x14: x = 900, y = -900 (0xFC7C), z = 16
  bytes[0x0C] = 0x84;
  bytes[0x0D] = 0x03;
  bytes[0x0E] = 0x7C;
  bytes[0x0F] = 0xFC;
  bytes[0x10] = 0x10;
  bytes[0x11] = 0x00;
  // EUL 0x1A..0x1F ignored (set to noise)
  for (int i = 0x12; i < 0x18; ++i) bytes[i] = 0xA5;
  // QUA 0x20: w = 0, x = 16384 (0x4000), y = 0, z = 0: 180 deg about x
  bytes[0x1A] = 0x00;
  bytes[0x1B] = 0x40;
  // TEMP 0x34 = 0xE7 = -25
  bytes[0x2C] = 0xE7;

  const bno055::RawBurst raw = bno055::unpack_burst(bytes);
  EXPECT_EQ(raw.acc, (std::array<std::int16_t, 3>{100, -981, 256}));
  EXPECT_EQ(raw.mag, (std::array<std::int16_t, 3>{16, -32, 0}));
  EXPECT_EQ(raw.gyr, (std::array<std::int16_t, 3>{900, -900, 16}));
  EXPECT_EQ(raw.qua, (std::array<std::int16_t, 4>{0, 16384, 0, 0}));
  EXPECT_EQ(raw.temp, -25);

  const bno055::ScaledBurst rps = bno055::scale_burst(raw, true);
  EXPECT_DOUBLE_EQ(rps.accel_m_s2.x(), 1.0);
  EXPECT_DOUBLE_EQ(rps.accel_m_s2.y(), -9.81);
  EXPECT_DOUBLE_EQ(rps.accel_m_s2.z(), 2.56);
  EXPECT_DOUBLE_EQ(rps.mag_uT.x(), 1.0);
  EXPECT_DOUBLE_EQ(rps.mag_uT.y(), -2.0);
  EXPECT_DOUBLE_EQ(rps.gyro_rad_s.x(), 1.0);  // 900 LSB = 1 rad/s
  EXPECT_DOUBLE_EQ(rps.gyro_rad_s.y(), -1.0);
  ASSERT_TRUE(rps.q_chipworld_body.has_value());
  EXPECT_DOUBLE_EQ(rps.q_chipworld_body->w(), 0.0);
  EXPECT_DOUBLE_EQ(rps.q_chipworld_body->x(), 1.0);
  EXPECT_DOUBLE_EQ(rps.temperature_c, -25.0);

  const bno055::ScaledBurst dps = bno055::scale_burst(raw, false);
  EXPECT_DOUBLE_EQ(dps.gyro_rad_s.z(), kPi / 180.0);  // 16 LSB = 1 dps
  EXPECT_DOUBLE_EQ(dps.gyro_rad_s.x(), 900.0 / 16.0 * kPi / 180.0);

  bno055::RawBurst zero_q = raw;
  zero_q.qua = {0, 0, 0, 0};
  EXPECT_FALSE(bno055::scale_burst(zero_q, true).q_chipworld_body.has_value());
}

TEST(Bno055Protocol, ParserSkipsGarbageBeforeTheStartByte) {
  RxRing ring;
  const std::array<std::uint8_t, 7> in{0x00, 0x55, 0xFF, 0xBB, 0x02, 0xA0, 0xFB};
  ring.push(in);
  std::array<std::uint8_t, 8> out{};
  const bno055::Response r = bno055::parse_response(ring, 2, out);
  EXPECT_EQ(r.kind, ResponseKind::kReadData);
  EXPECT_EQ(r.garbage_bytes, 3u);
  EXPECT_EQ(out[0], 0xA0);
  EXPECT_EQ(out[1], 0xFB);
  EXPECT_TRUE(ring.empty());
}

TEST(Bno055Protocol, ParserWaitsForAFrameSplitAcrossReads) {
  RxRing ring;
  std::array<std::uint8_t, 8> out{};
  const std::array<std::uint8_t, 3> first{0xBB, 0x03, 0x11};
  ring.push(first);
  EXPECT_EQ(bno055::parse_response(ring, 3, out).kind, ResponseKind::kIncomplete);
  EXPECT_EQ(ring.size(), 3u);  // kept for the next read
  const std::array<std::uint8_t, 2> rest{0x22, 0x33};
  ring.push(rest);
  EXPECT_EQ(bno055::parse_response(ring, 3, out).kind, ResponseKind::kReadData);
  EXPECT_EQ(out[0], 0x11);
  EXPECT_EQ(out[2], 0x33);
  // A lone start byte is incomplete too.
  const std::array<std::uint8_t, 1> lone{0xEE};
  ring.push(lone);
  EXPECT_EQ(bno055::parse_response(ring, 0, out).kind, ResponseKind::kIncomplete);
}

TEST(Bno055Protocol, ParserRejectsAWrongLengthAndAnUnknownStatus) {
  RxRing ring;
  std::array<std::uint8_t, 8> out{};
  const std::array<std::uint8_t, 4> wrong{0xBB, 0x05, 0x01, 0x02};
  ring.push(wrong);
  EXPECT_EQ(bno055::parse_response(ring, 2, out).kind, ResponseKind::kBadFrame);
  EXPECT_EQ(ring.size(), 3u);  // only the false start byte went
  ring.drop_all();
  const std::array<std::uint8_t, 2> unknown{0xEE, 0x42};
  ring.push(unknown);
  EXPECT_EQ(bno055::parse_response(ring, 0, out).kind, ResponseKind::kBadFrame);
  const std::array<std::uint8_t, 2> nothing_asked{0xBB, 0x01};
  ring.drop_all();
  ring.push(nothing_asked);
  EXPECT_EQ(bno055::parse_response(ring, 0, out).kind, ResponseKind::kBadFrame);
}

TEST(Bno055Protocol, ParserReturnsTypedStatus) {
  RxRing ring;
  std::array<std::uint8_t, 8> out{};
  const std::array<std::uint8_t, 4> in{0xEE, 0x07, 0xEE, 0x01};
  ring.push(in);
  bno055::Response r = bno055::parse_response(ring, 45, out);
  EXPECT_EQ(r.kind, ResponseKind::kStatus);
  EXPECT_EQ(r.status, UartStatus::kBusOverRunError);
  EXPECT_EQ(bno055::to_string(r.status), "BUS_OVER_RUN_ERROR");
  r = bno055::parse_response(ring, 0, out);
  EXPECT_EQ(r.status, UartStatus::kWriteSuccess);
  EXPECT_TRUE(ring.empty());
}

// ---- the driver against the simulator -------------------------------------------------------

// Every sample is exactly what the sim served for its burst index, indices strictly
// increase (none duplicated or invented) and stamps increase.
void expect_samples_genuine(const std::vector<ImuSample>& samples, bool gyro_rps = true) {
  std::int64_t last_n = -1;
  TimeNs last_t = 0;
  for (const ImuSample& s : samples) {
    const std::uint32_t n = burst_index(s);
    const bno055::ScaledBurst want = bno055::scale_burst(test::bno055_motion(n), gyro_rps);
    ASSERT_GT(static_cast<std::int64_t>(n), last_n);
    ASSERT_EQ(s.accel_m_s2, want.accel_m_s2) << "burst " << n;
    ASSERT_EQ(s.gyro_rad_s, want.gyro_rad_s) << "burst " << n;
    ASSERT_TRUE(s.mag_uT.has_value());
    ASSERT_EQ(*s.mag_uT, want.mag_uT);
    ASSERT_TRUE(s.q_chipworld_body.has_value());
    ASSERT_EQ(s.q_chipworld_body->coeffs(), want.q_chipworld_body->coeffs());
    ASSERT_EQ(s.temperature_c, want.temperature_c);
    ASSERT_GT(s.t_ns, last_t);
    ASSERT_GE(s.publish_t_ns, s.t_ns);
    last_n = n;
    last_t = s.t_ns;
  }
}

// Burst indices are consecutive: nothing was lost.
void expect_no_gaps(const std::vector<ImuSample>& samples) {
  for (std::size_t i = 1; i < samples.size(); ++i) {
    ASSERT_EQ(burst_index(samples[i]), burst_index(samples[i - 1]) + 1) << "sample " << i;
  }
}

TEST(Bno055Uart, ResetsConfiguresAndStreams) {
  Bno055Rig rig;
  EXPECT_EQ(rig.driver->state(), ImuDriverState::kReset);
  ASSERT_TRUE(rig.reach_run()) << format_counters(rig.counters());
  EXPECT_EQ(rig.sim.resets_seen, 1u);
  EXPECT_EQ(rig.sim.regs[0x3B], 0x02);  // UNIT_SEL: rad/s, m/s^2, deg C, Windows
  EXPECT_EQ(rig.sim.regs[0x3D], 0x0C);  // OPR_MODE: NDOF
  EXPECT_EQ(rig.sim.regs[0x3E], 0x00);  // PWR_MODE: normal
  rig.run_for(kNsPerS);
  const auto& s = rig.sink.samples;
  EXPECT_GE(s.size(), 95u);
  EXPECT_LE(s.size(), 101u);
  expect_samples_genuine(s);
  expect_no_gaps(s);
  EXPECT_DOUBLE_EQ(s.back().gyro_rad_s.z(), 0.5);  // 450 LSB at 900 LSB/(rad/s)
  const ImuCounters& c = rig.counters();
  EXPECT_EQ(c.samples, s.size());
  EXPECT_EQ(c.bad_transfer, 0u);
  EXPECT_EQ(c.dropped_samples, 0u);
  EXPECT_EQ(c.resets, 0u);
  EXPECT_EQ(c.resync, 0u);
  EXPECT_GE(rig.driver->config_rechecks(), 9u);  // one per 10 samples
  EXPECT_EQ(c.config_mismatch, 0u);
}

TEST(Bno055Uart, GyroInDegreesPerSecondWhenConfigured) {
  Bno055UartConfig cfg;
  cfg.gyro_in_rps = false;
  Bno055Rig rig(cfg);
  ASSERT_TRUE(rig.reach_run());
  EXPECT_EQ(rig.sim.regs[0x3B], 0x00);
  rig.run_for(100 * kNsPerMs);
  ASSERT_FALSE(rig.sink.samples.empty());
  expect_samples_genuine(rig.sink.samples, false);
  EXPECT_DOUBLE_EQ(rig.sink.samples.back().gyro_rad_s.z(), 450.0 / 16.0 * kPi / 180.0);
}

TEST(Bno055Uart, StampsAreReceiveTimeMinusWireTimeMinusLatency) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(20 * kNsPerMs);
  ASSERT_FALSE(rig.sink.samples.empty());
  const ImuSample& first = rig.sink.samples.front();
  // 0xBB len + 45 data bytes at 115200 baud, then the documented processing latency.
  const DurationNs wire_ns = 47 * serial_byte_time_ns(115200);
  EXPECT_EQ(first.t_ns, first.publish_t_ns - wire_ns - kBno055ProcessingLatencyNs);
  rig.run_for(kNsPerS);
  for (std::size_t i = 1; i < rig.sink.samples.size(); ++i) {
    const DurationNs dt = rig.sink.samples[i].t_ns - rig.sink.samples[i - 1].t_ns;
    EXPECT_NEAR(static_cast<double>(dt), 1e7, 1e5) << i;  // the 100 Hz poll grid
  }
}

TEST(Bno055Uart, GarbageBeforeAFrameIsSkippedAndCounted) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);
  rig.sim.garbage_next = 7;
  rig.run_for(100 * kNsPerMs);
  rig.drain();
  const ImuCounters& c = rig.counters();
  EXPECT_EQ(c.resync, 1u);
  EXPECT_GE(rig.driver->uart_counters().garbage_bytes, 7u);
  EXPECT_EQ(c.dropped_samples, 0u);
  EXPECT_EQ(c.bad_transfer, 0u);
  EXPECT_EQ(rig.sim.garbage_next, 0u);  // the fault was injected
  expect_samples_genuine(rig.sink.samples);
  expect_no_gaps(rig.sink.samples);
  EXPECT_EQ(c.samples, rig.sim.bursts_served);
}

TEST(Bno055Uart, AFrameSplitAcrossReadsIsReassembled) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);
  const std::uint64_t partial_before = rig.driver->uart_counters().partial_reads;
  rig.sim.split_next = true;
  rig.run_for(100 * kNsPerMs);
  rig.drain();
  EXPECT_FALSE(rig.sim.split_next);
  EXPECT_GE(rig.driver->uart_counters().partial_reads, partial_before + 1);
  EXPECT_EQ(rig.counters().dropped_samples, 0u);
  EXPECT_EQ(rig.counters().bad_transfer, 0u);
  expect_samples_genuine(rig.sink.samples);
  expect_no_gaps(rig.sink.samples);
  EXPECT_EQ(rig.counters().samples, rig.sim.bursts_served);
}

TEST(Bno055Uart, AWrongLengthByteDropsThatSampleOnly) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);
  const std::uint64_t bad_burst = rig.sim.bursts_served;
  rig.sim.wrong_length_next = 3;
  rig.run_for(200 * kNsPerMs);
  rig.drain();
  const ImuCounters& c = rig.counters();
  EXPECT_GE(c.resync, 1u);
  EXPECT_EQ(c.bad_transfer, 1u);
  EXPECT_EQ(c.dropped_samples, 1u);
  EXPECT_EQ(c.resets, 0u);
  EXPECT_EQ(rig.driver->state(), ImuDriverState::kRun);
  expect_samples_genuine(rig.sink.samples);
  EXPECT_EQ(c.samples, rig.sim.bursts_served - 1);
  for (const ImuSample& s : rig.sink.samples) EXPECT_NE(burst_index(s), bad_burst);
  EXPECT_GT(burst_index(rig.sink.samples.back()), bad_burst);  // and it streams on
}

TEST(Bno055Uart, ReadFailStatusIsANackAndADrop) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);
  const std::size_t before = rig.sink.samples.size();
  rig.sim.status_next = 0x02;  // READ_FAIL
  rig.sim.status_next_count = 1;
  rig.run_for(200 * kNsPerMs);
  const ImuCounters& c = rig.counters();
  EXPECT_EQ(c.nack, 1u);
  EXPECT_EQ(c.bad_transfer, 1u);
  EXPECT_EQ(c.dropped_samples, 1u);
  EXPECT_EQ(rig.driver->uart_counters().status[0x02], 1u);
  EXPECT_GT(rig.sink.samples.size(), before + 15);
  expect_samples_genuine(rig.sink.samples);
  expect_no_gaps(rig.sink.samples);  // the failed read consumed no burst on the sim
}

TEST(Bno055Uart, BusOverRunIsRetriedAtOnceWithoutLosingTheSample) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);
  rig.sim.status_next = 0x07;  // BUS_OVER_RUN_ERROR, twice in a row
  rig.sim.status_next_count = 2;
  rig.run_for(200 * kNsPerMs);
  const ImuCounters& c = rig.counters();
  EXPECT_EQ(rig.driver->uart_counters().overrun_retries, 2u);
  EXPECT_EQ(rig.driver->uart_counters().status[0x07], 2u);
  EXPECT_EQ(c.nack, 2u);
  EXPECT_EQ(c.bad_transfer, 0u);
  EXPECT_EQ(c.dropped_samples, 0u);
  expect_samples_genuine(rig.sink.samples);
  expect_no_gaps(rig.sink.samples);
}

TEST(Bno055Uart, PersistentBusOverRunGivesUpOnThatTick) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);
  rig.sim.status_next = 0x07;
  rig.sim.status_next_count = 4;  // 1 try + 3 retries, all refused
  rig.run_for(200 * kNsPerMs);
  const ImuCounters& c = rig.counters();
  EXPECT_EQ(rig.driver->uart_counters().overrun_retries, 3u);
  EXPECT_EQ(c.bad_transfer, 1u);
  EXPECT_EQ(c.dropped_samples, 1u);
  EXPECT_EQ(rig.driver->state(), ImuDriverState::kRun);
  expect_samples_genuine(rig.sink.samples);
}

TEST(Bno055Uart, AResponseThatNeverComesTimesOutAndIsRetried) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(100 * kNsPerMs);
  const std::size_t before = rig.sink.samples.size();
  const std::uint64_t timeouts_before = rig.driver->uart_counters().timeouts;  // boot probes
  rig.sim.ignore_next = 1;
  rig.run_for(200 * kNsPerMs);
  const ImuCounters& c = rig.counters();
  EXPECT_EQ(rig.driver->uart_counters().timeouts, timeouts_before + 1);
  EXPECT_EQ(c.bad_transfer, 1u);
  // The lost tick plus the ticks that passed while waiting for it (20 ms timeout at 100 Hz).
  EXPECT_GE(c.dropped_samples, 1u);
  EXPECT_LE(c.dropped_samples, 3u);
  EXPECT_EQ(c.resets, 0u);
  EXPECT_GT(rig.sink.samples.size(), before + 10);
  expect_samples_genuine(rig.sink.samples);
}

TEST(Bno055Uart, WrongChipIdNeverRunsAndIsCounted) {
  Bno055Rig rig;
  rig.sim.chip_id = 0x55;
  EXPECT_FALSE(rig.reach_run(3 * kNsPerS));
  EXPECT_GE(rig.counters().probe_failures, 2u);
  EXPECT_GE(rig.counters().resets, 2u);
  EXPECT_TRUE(rig.sink.samples.empty());
  EXPECT_EQ(rig.sim.bursts_served, 0u);
  // The right chip appears: the driver gets there on its own.
  rig.sim.chip_id = 0xA0;
  ASSERT_TRUE(rig.reach_run(3 * kNsPerS));
  rig.run_for(100 * kNsPerMs);
  EXPECT_FALSE(rig.sink.samples.empty());
  expect_samples_genuine(rig.sink.samples);
}

TEST(Bno055Uart, UnpluggedAndBackResetsAndStreamsAgain) {
  Bno055UartConfig cfg;
  Bno055Rig rig(cfg);
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(200 * kNsPerMs);
  rig.drain();
  const std::size_t before = rig.sink.samples.size();
  ASSERT_GT(before, 15u);
  rig.sim.silent = true;  // unplugged: nothing answers
  rig.run_for(3 * kNsPerS);
  const ImuCounters& c = rig.counters();
  EXPECT_EQ(rig.sink.samples.size(), before);  // nothing invented while it was gone
  EXPECT_GT(c.bad_transfer, static_cast<std::uint64_t>(cfg.max_failures));
  EXPECT_GE(c.resets, 2u);  // the failure limit, then the probe timeout
  EXPECT_GE(c.probe_failures, 1u);
  EXPECT_NE(rig.driver->state(), ImuDriverState::kRun);
  const std::uint64_t resets_seen = rig.sim.resets_seen;

  const std::uint64_t writes_seen = rig.sim.writes_seen;
  rig.sim.silent = false;  // plugged back in
  ASSERT_TRUE(rig.reach_run(3 * kNsPerS)) << format_counters(rig.counters());
  // Configured anew (the reset request itself may have been lost while it was unplugged, as
  // a real chip that lost power boots fresh anyway).
  EXPECT_GE(rig.sim.resets_seen, resets_seen);
  EXPECT_GE(rig.sim.writes_seen, writes_seen + 4);
  rig.run_for(200 * kNsPerMs);
  EXPECT_GT(rig.sink.samples.size(), before + 15);
  expect_samples_genuine(rig.sink.samples);
}

TEST(Bno055Uart, ConfigChangedBehindItsBackIsFoundAndRestored) {
  Bno055Rig rig;
  ASSERT_TRUE(rig.reach_run());
  rig.run_for(300 * kNsPerMs);
  ASSERT_GT(rig.driver->config_rechecks(), 0u);
  EXPECT_EQ(rig.counters().config_mismatch, 0u);
  rig.sim.regs[0x3B] = 0x80;  // UNIT_SEL back to its reset value: dps, Android
  rig.sim.regs[0x3D] = 0x07;  // and OPR_MODE AMG: no fusion
  ASSERT_TRUE(rig.run_until([&rig] { return rig.counters().config_mismatch > 0; }, kNsPerS));
  EXPECT_EQ(rig.counters().config_mismatch, 1u);
  ASSERT_TRUE(rig.reach_run());
  EXPECT_EQ(rig.counters().resets, 1u);
  EXPECT_EQ(rig.sim.regs[0x3B], 0x02);
  EXPECT_EQ(rig.sim.regs[0x3D], 0x0C);
  const std::size_t before = rig.sink.samples.size();
  rig.run_for(200 * kNsPerMs);
  EXPECT_GT(rig.sink.samples.size(), before + 15);
  expect_samples_genuine(rig.sink.samples);
}

TEST(Bno055Uart, BadConfigurationAndMissingDeviceAreOneLineErrors) {
  test::CollectSink sink;
  Bno055UartConfig cfg;
  cfg.device = "/dev/wallar-no-such-tty";
  EXPECT_THROW(Bno055Uart(cfg, sink), SerialError);
  cfg.rate_hz = 200.0;
  try {
    Bno055Uart driver(cfg, sink);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/dev/wallar-no-such-tty"));
    EXPECT_THAT(e.what(), HasSubstr("rate_hz 200"));
  }
}

}  // namespace
}  // namespace wallar::drivers
