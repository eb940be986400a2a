// SPDX-License-Identifier: Apache-2.0
// erg-worker: runs one job, as one MPI rank of P (docs/design.md, "Processes"):
//   mpirun -n P erg-worker JOB.json --out DIR [--tiles PXxPY] [...]
// or alone (one rank, one tile). Started by `erg run` (which draws the
// progress bar from the erg.v1.WorkerEvent lines rank 0 writes to
// --progress-fd) or directly.
#include <mpi.h>

#include <cstdlib>
#include <iostream>

#include "dist/decomposition.h"
#include "job/run_flags.h"
#include "sim/runner.h"

int main(int argc, char** argv) {
  // Open MPI 4.1's default MPI-IO component (ompio) corrupts or fails
  // collective compressed writes of parallel HDF5 1.10 at random (measured
  // here: 4 runs of 5 failed with 3 ranks); ROMIO does not. A user's own
  // choice (the variable already set) wins.
  ::setenv("OMPI_MCA_io", "romio321", 0);
  int provided = 0;
  // OpenMP threads inside a rank never call MPI.
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  erg::job::RunFlags flags;
  erg::RunConfig cfg;
  try {
    flags = erg::job::parse_run_flags(std::vector<std::string>(argv + 1, argv + argc));
    if (flags.ranks > 0)
      throw std::invalid_argument("--ranks is for erg run; start erg-worker with mpirun -n P");
    if (!flags.tiles.empty()) erg::dist::parse_tiles(flags.tiles, cfg.tiles_x, cfg.tiles_y);
  } catch (const std::exception& e) {
    if (rank == 0) std::cerr << "erg-worker: " << e.what() << "\n";
    MPI_Finalize();
    return 2;
  }
  cfg.job_path = flags.job_path;
  cfg.out_dir = flags.out_dir;
  cfg.resume = !flags.resume_dir.empty();
  cfg.overrides = flags.overrides;
  cfg.options.threads = flags.threads;
  cfg.options.backend = flags.backend == "cpu"    ? erg::BackendKind::kCpu
                        : flags.backend == "cuda" ? erg::BackendKind::kCuda
                                                  : erg::BackendKind::kAuto;
  cfg.progress_fd = flags.progress_fd;
  cfg.steer_dir = flags.steer_dir;
  cfg.quiet = flags.quiet;
  const int code = erg::run_job(cfg);
  MPI_Finalize();
  return code;
}
