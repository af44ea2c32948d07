// SPDX-License-Identifier: Apache-2.0
/// @file bno055_sim.hpp
/// @brief A BNO055 on the master side of a pseudo-terminal: the driver opens the slave path
/// through the production SerialPort and gets real bytes through the tty layer.
///
/// The sim is pumped from the test loop (deterministic): pump() handles every complete
/// request that has arrived, answering like the chip (datasheet 4.7) from a register file
/// whose data registers follow synthetic motion: the n-th burst read served carries
/// motion(n). Faults are injected one response at a time (garbage before it, split across
/// two pumps, wrong length byte, an error status, no answer) or persistently (silent, a
/// wrong chip id).
///
/// Threading: test thread only.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "wallar/core/time.hpp"
#include "wallar/drivers/imu/bno055_protocol.hpp"

namespace wallar::test {

/// The raw registers of the n-th burst the sim serves: acc.x carries n itself, so a test can
/// tell which burst a sample came from and that none was invented or duplicated.
drivers::bno055::RawBurst bno055_motion(std::uint32_t n);

class Bno055Sim {
 public:
  /// What the n-th burst read carries, answered at now_ns (the sim's clock).
  using Motion = std::function<drivers::bno055::RawBurst(std::uint64_t n, TimeNs now_ns)>;

  /// A pty of its own, serving bno055_motion(n).
  Bno055Sim();
  /// Answers on `fd`, which the caller opened (a tty, a socket) and keeps: the
  /// hardware-in-the-loop host side (tests/hil/bno055_host.cpp) serves a recording this way.
  Bno055Sim(int fd, Motion motion);
  ~Bno055Sim();
  Bno055Sim(const Bno055Sim&) = delete;
  Bno055Sim& operator=(const Bno055Sim&) = delete;

  [[nodiscard]] const std::string& slave_path() const { return slave_path_; }
  [[nodiscard]] int master_fd() const { return master_; }

  /// Reads the requests that arrived, waiting (real time, bounded) until `requests_expected`
  /// requests have been seen in total; answers each one. Also sends the second half of a
  /// response split at the previous pump. Returns the bytes written.
  std::size_t pump(TimeNs now_ns, std::uint64_t requests_expected);

  // The register file (page 0). Tests may poke it behind the driver's back.
  std::array<std::uint8_t, 0x80> regs{};

  // Persistent faults.
  bool silent = false;                  //!< unplugged: requests are read and never answered
  std::uint8_t chip_id = 0xA0;          //!< what CHIP_ID reads after boot
  DurationNs boot_ns = 650 * kNsPerMs;  //!< no answers this long after RST_SYS

  // One-shot faults, for the next response(s) to a burst read.
  std::size_t garbage_next = 0;     //!< garbage bytes (no 0xBB/0xEE) before the response
  bool split_next = false;          //!< first half now, second half at the next pump
  int wrong_length_next = 0;        //!< added to the length byte of the next burst response
  int status_next_count = 0;        //!< bursts answered 0xEE status_next instead of data
  std::uint8_t status_next = 0x02;  //!< READ_FAIL
  int ignore_next = 0;              //!< burst reads not answered at all

  // What the sim saw and did.
  std::uint64_t requests_seen = 0;
  std::uint64_t bursts_served = 0;  //!< burst responses sent with data (n of motion(n))
  std::uint64_t resets_seen = 0;
  std::uint64_t writes_seen = 0;

 private:
  void handle(const std::uint8_t* req, std::size_t len, TimeNs now_ns, bool write);
  void answer_burst(std::uint8_t reg, std::uint8_t len, TimeNs now_ns);
  void send(const std::vector<std::uint8_t>& bytes);
  void reset_registers();

  int master_ = -1;
  int slave_ = -1;
  bool owns_fds_ = true;
  Motion motion_;
  std::string slave_path_;
  std::vector<std::uint8_t> rx_;
  std::vector<std::uint8_t> out_;       // bytes to write at the end of this pump
  std::vector<std::uint8_t> deferred_;  // second half of a split response
  TimeNs boot_until_ns_ = 0;
};

}  // namespace wallar::test
