// SPDX-License-Identifier: Apache-2.0
/// @file cmd_eval.cpp
/// @brief `wallar eval ...`: the evaluation suite (tools/eval). Each experiment is its own
/// subcommand; `wallar eval all` runs every one of them into one folder.
#include "commands.hpp"

namespace wallar::cli {

void add_eval_command(CLI::App& app, std::function<int()>& run) {
  CLI::App* eval = app.add_subcommand(
      "eval", "Evaluation suite: the thesis's experiments, runtime, real data, marker truth");
  eval->require_subcommand(1);
  add_eval_marker_command(*eval, run);
  (void)run;
}

}  // namespace wallar::cli
