// SPDX-License-Identifier: Apache-2.0
// Runs a command (no shell) and captures its output: sbatch, squeue, scancel.
#pragma once

#include <string>
#include <vector>

namespace erg::server {

struct CommandResult {
  int exit_code = -1;  // 128 + signal when killed; 127 when it could not start
  std::string out;     // stdout
  std::string err;     // stderr
};

// Blocks until the command ends or timeout_s passes (then it is killed).
CommandResult run_command(const std::vector<std::string>& argv, double timeout_s = 60);

}  // namespace erg::server
