// SPDX-License-Identifier: Apache-2.0
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
//
// Steering (RunConfig::steer_dir, erg-worker --steer-dir DIR): at every step
// boundary before step S (the run's first step included, its end excluded)
// rank 0 takes the files DIR/NAME.json in name order (other names, such as
// NAME.json.tmp while a writer is still at it, are left alone), each one
// erg.v1.Event in protobuf JSON. Its step, if any, is replaced by S; it is
// defaults-filled and validated as the job's next event. A good one is
// appended to the job's events on every rank (so it applies at the start of
// step S after the job's own events at S, in file order, and is carried by
// later checkpoints and snapshots), DIR_OUT/job.json is rewritten with it,
// then the file is renamed NAME.applied and a "steered" progress event names
// it. A bad one is renamed NAME.rejected with a "steer_rejected" event giving
// the reason, and the run goes on. Tiled runs learn of pending steering from
// the per-step control broadcast, so a step without any costs nothing more.
// Re-running the recorded DIR_OUT/job.json reproduces the run bitwise.
//
// Resume: from the newest checkpoint that proves its integrity (checksums)
// and agrees with DIR/job.json, events included; each newer one passed over
// is named with its reason (sim/resume_point.h). The checkpoint's spec lacks
// the events steered after it was written: job.json's extend them, and the
// run continues with job.json's, so the steps it redoes see those events at
// the steps they were steered at.
#pragma once

#include <mpi.h>

#include <string>

#include "io/run_files.h"  // step_name
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
  std::string steer_dir;         // steering events to apply (see above); "" = none
  bool quiet = false;            // no periodic log lines on stderr
};

// Runs to completion on the ranks of `world` (MPI is initialised); returns
// the process exit code (0 done, 2 bad input, 1 failure, 130/143 stopped by
// SIGINT/SIGTERM after a final checkpoint). Collective.
int run_job(const RunConfig& cfg, MPI_Comm world = MPI_COMM_WORLD);

// Newest checkpoint in DIR/checkpoints a resume would take (intact, agreeing
// with DIR/job.json; sim/resume_point.h), or "" when there is none.
std::string latest_checkpoint(const std::string& out_dir);

}  // namespace erg
