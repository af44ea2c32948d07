// SPDX-License-Identifier: Apache-2.0
/// @file main.cpp
/// @brief The wallar executable: one binary, one subcommand per job.
#include <csignal>
#include <cstdio>
#include <exception>

#include "commands.hpp"
#include "wallar/core/error.hpp"

namespace wallar::cli {

std::atomic<bool>& stop_requested() {
  static std::atomic<bool> flag{false};
  static_assert(std::atomic<bool>::is_always_lock_free,
                "the signal handler needs a lock-free flag");
  return flag;
}

std::atomic<int>& stop_signal() {
  static std::atomic<int> signo{0};
  static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free int");
  return signo;
}

std::atomic<bool>& stats_requested() {
  static std::atomic<bool> flag{false};
  return flag;
}

}  // namespace wallar::cli

namespace {

void on_stop_signal(int signo) {
  wallar::cli::stop_signal().store(signo);
  wallar::cli::stop_requested().store(true);
}
void on_stats_signal(int /*signo*/) { wallar::cli::stats_requested().store(true); }

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  struct sigaction stats {};
  stats.sa_handler = on_stats_signal;
  sigemptyset(&stats.sa_mask);
  stats.sa_flags = SA_RESTART;
  sigaction(SIGUSR1, &stats, nullptr);  // `wallar run` prints its stats table
}

}  // namespace

int main(int argc, char** argv) {
  using namespace wallar::cli;
  CLI::App app{"wallar: stereo video see-through AR headset firmware and tools"};
  app.set_version_flag("--version", "wallar 0.1.0");
  app.require_subcommand(1);
  app.fallthrough(false);
  std::function<int()> run;
  add_run_command(app, run);
  add_replay_command(app, run);
  add_record_command(app, run);
  add_bench_command(app, run);
  add_walls_command(app, run);
  add_eval_command(app, run);
  add_imu_command(app, run);
  add_track_command(app, run);
  add_render_command(app, run);
  add_calibrate_command(app, run);
  add_convert_command(app, run);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "wallar: %s\n", e.what());
    std::fprintf(stderr, "Run with --help for usage.\n");
    return kExitUsage;
  }

  install_signal_handlers();
  try {
    return run ? run() : kExitUsage;
  } catch (const wallar::InputError& e) {
    std::fprintf(stderr, "wallar: error: %s\n", e.what());
    return kExitBadInput;
  } catch (const CLI::Error& e) {  // an option value found wrong after parsing
    std::fprintf(stderr, "wallar: error: %s\n", e.what());
    return kExitUsage;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "wallar: error: %s\n", e.what());
    return kExitFailure;
  }
}
