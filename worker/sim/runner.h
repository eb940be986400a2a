// A whole run as erg-worker performs it: load or resume, step, and write
// snapshots, previews and checkpoints at the job's cadence, reporting
// progress. Output directory layout (README, "Outputs"):
//   DIR/job.json                          the defaults-filled job spec
//   DIR/snapshots/step_NNNNNNNN.h5 (.xdmf) float32 fields + exact totals
//   DIR/previews/step_NNNNNNNN.png        hillshaded previews
//   DIR/checkpoints/step_NNNNNNNN.h5      exact integer state (last two kept)
#pragma once

#include <string>

#include "job/spec.h"
#include "sim/simulation.h"

namespace erg {

struct RunConfig {
  std::string job_path;  // new run
  std::string out_dir;
  bool resume = false;  // continue the run in out_dir from its latest checkpoint
  job::Overrides overrides;
  RunOptions options;
  int progress_fd = -1;  // JSON-lines progress events go here (erg's progress bar)
  bool quiet = false;    // no periodic log lines on stderr
};

// Runs to completion; returns the process exit code (0 done, 2 bad input,
// 1 failure, 130/143 stopped by SIGINT/SIGTERM after a final checkpoint).
int run_job(const RunConfig& cfg);

// Latest readable checkpoint in DIR/checkpoints, or "" when there is none.
std::string latest_checkpoint(const std::string& out_dir);

std::string step_name(std::int64_t step);  // "step_00000042"

}  // namespace erg
