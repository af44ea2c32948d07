// SPDX-License-Identifier: Apache-2.0
/// @file bno055_host.cpp
/// @brief The host side of the hardware-in-the-loop boot test: a BNO055 on the other end of
/// the guest's UART (QEMU's serial chardev), answering the product's driver with a recording's
/// IMU stream in real time.
///
///   wallar_bno055_host --tty PATH --recording DIR [--seconds S]
///
/// PATH is the pty QEMU made for the guest's PL011 (`-chardev pty`); the sim opens it like a
/// device and answers every request as the chip would (tests/unit/bno055_sim.hpp, the same sim
/// the driver's unit tests use). The n-th burst read carries the recording's IMU sample at the
/// time since the first burst (looping over the recording), scaled as UNIT_SEL asks. On
/// SIGTERM/SIGINT (or after S seconds) it prints one line of counters and exits 0; the boot
/// test compares them with the samples the product counted in the guest.
///
/// Threading: one thread.
#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <string_view>

#include "../unit/bno055_sim.hpp"
#include "wallar/core/time.hpp"
#include "wallar/drivers/imu/bno055_registers.hpp"
#include "wallar/drivers/recording/euroc.hpp"

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int /*signo*/) { g_stop.store(true); }

std::int16_t to_i16(double v) {
  return static_cast<std::int16_t>(std::clamp(std::lround(v), -32768L, 32767L));
}

int usage() {
  std::fprintf(stderr, "usage: wallar_bno055_host --tty PATH --recording DIR [--seconds S]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace wallar;
  std::string tty;
  std::string recording;
  double seconds = 0.0;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (i + 1 >= argc) return usage();
    if (a == "--tty") {
      tty = argv[++i];
    } else if (a == "--recording") {
      recording = argv[++i];
    } else if (a == "--seconds") {
      seconds = std::atof(argv[++i]);
    } else {
      return usage();
    }
  }
  if (tty.empty() || recording.empty()) return usage();
  try {
    const recording::EurocRecording rec = recording::read_euroc(recording);
    if (rec.imu.size() < 2) {
      std::fprintf(stderr, "wallar_bno055_host: %s: the recording has no IMU stream\n",
                   recording.c_str());
      return 1;
    }
    const int fd = ::open(tty.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (fd < 0) {
      std::fprintf(stderr, "wallar_bno055_host: %s: %s\n", tty.c_str(), std::strerror(errno));
      return 1;
    }
    termios tio{};
    if (::tcgetattr(fd, &tio) == 0) {
      ::cfmakeraw(&tio);
      ::tcsetattr(fd, TCSANOW, &tio);
    }
    std::signal(SIGTERM, on_signal);
    std::signal(SIGINT, on_signal);

    const TimeNs t0_rec = rec.imu.front().t_ns;
    const DurationNs span_ns = rec.imu.back().t_ns - t0_rec;
    TimeNs first_burst_ns = -1;
    test::Bno055Sim* sim_ptr = nullptr;
    test::Bno055Sim sim(fd, [&](std::uint64_t /*n*/, TimeNs now_ns) {
      if (first_burst_ns < 0) first_burst_ns = now_ns;
      const TimeNs t_rec = t0_rec + (now_ns - first_burst_ns) % span_ns;
      const auto it = std::upper_bound(rec.imu.begin(), rec.imu.end(), t_rec,
                                       [](TimeNs t, const ImuSample& s) { return t < s.t_ns; });
      const ImuSample& s = *(it == rec.imu.begin() ? it : it - 1);
      const std::uint8_t unit_sel =
          sim_ptr->regs[drivers::bno055::reg_addr(drivers::bno055::Reg::kUnitSel)];
      const bool accel_mg = (unit_sel & 0x01) != 0;
      const bool gyro_rps = (unit_sel & 0x02) != 0;
      drivers::bno055::RawBurst r;
      for (int i = 0; i < 3; ++i) {
        r.acc[i] = to_i16(accel_mg ? s.accel_m_s2[i] / 0.00980665 : s.accel_m_s2[i] * 100.0);
        r.gyr[i] = to_i16(gyro_rps ? s.gyro_rad_s[i] * 900.0 : s.gyro_rad_s[i] * 180.0 / M_PI * 16);
      }
      r.mag = {320, 0, -640};    // 20, 0, -40 uT: a still field
      r.qua = {16384, 0, 0, 0};  // identity: the recording carries no fused attitude
      r.temp = 25;
      return r;
    });
    sim_ptr = &sim;
    const TimeNs start_ns = monotonic_now_ns();
    while (!g_stop.load()) {
      sim.pump(monotonic_now_ns(), sim.requests_seen + 1);
      if (seconds > 0 && monotonic_now_ns() - start_ns > static_cast<TimeNs>(seconds * 1e9)) break;
    }
    std::printf("bno055-host: %llu requests, %llu bursts served, %llu resets, %llu writes\n",
                static_cast<unsigned long long>(sim.requests_seen),
                static_cast<unsigned long long>(sim.bursts_served),
                static_cast<unsigned long long>(sim.resets_seen),
                static_cast<unsigned long long>(sim.writes_seen));
    ::close(fd);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "wallar_bno055_host: %s\n", e.what());
    return 1;
  }
}
