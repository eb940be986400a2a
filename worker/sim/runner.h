// A whole run as erg-worker performs it, on one MPI rank or many: load or
// resume, step, and write snapshots, previews and checkpoints at the job's
// cadence, reporting progress. Output directory layout (README, "Outputs"):
//   DIR/job.json                          the defaults-filled job spec
//   DIR/snapshots/step_NNNNNNNN.h5 (.xdmf) float32 fields + exact totals
//   DIR/previews/step_NNNNNNNN.png        hillshaded previews
//   DIR/checkpoints/step_NNNNNNNN.h5      exact integer state (last two kept)
//
// With P ranks, rank 0 is the coordinator: it validates the job once, chooses
// the tile grid, broadcasts both, prints progress and decides when to stop.
// Every rank runs the pipeline on its tile; snapshots and checkpoints are
// single files written collectively (parallel HDF5). Any rank's error aborts
// the whole job with a message (MPI_Abort): no hang, no orphan ranks.
#pragma once

#include <mpi.h>

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
  int tiles_x = 0, tiles_y = 0;  // --tiles PXxPY (0: chosen)
  int progress_fd = -1;          // JSON-lines progress events (rank 0) go here
  bool quiet = false;            // no periodic log lines on stderr
};

// Runs to completion on the ranks of `world` (MPI is initialised); returns
// the process exit code (0 done, 2 bad input, 1 failure, 130/143 stopped by
// SIGINT/SIGTERM after a final checkpoint). Collective.
int run_job(const RunConfig& cfg, MPI_Comm world = MPI_COMM_WORLD);

// Latest readable checkpoint in DIR/checkpoints, or "" when there is none.
std::string latest_checkpoint(const std::string& out_dir);

std::string step_name(std::int64_t step);  // "step_00000042"

}  // namespace erg
