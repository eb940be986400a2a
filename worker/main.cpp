// erg-worker: runs one job (the MPI program of DESIGN.md section 1; on one
// tile here). Started by `erg run` (which draws the progress bar from the
// JSON lines on --progress-fd) or directly.
#include <iostream>

#include "job/run_flags.h"
#include "sim/runner.h"

int main(int argc, char** argv) {
  erg::job::RunFlags flags;
  try {
    flags = erg::job::parse_run_flags(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const std::exception& e) {
    std::cerr << "erg-worker: " << e.what() << "\n";
    return 2;
  }
  erg::RunConfig cfg;
  cfg.job_path = flags.job_path;
  cfg.out_dir = flags.out_dir;
  cfg.resume = !flags.resume_dir.empty();
  cfg.overrides = flags.overrides;
  cfg.options.threads = flags.threads;
  cfg.options.backend = flags.backend == "cpu"    ? erg::BackendKind::kCpu
                        : flags.backend == "cuda" ? erg::BackendKind::kCuda
                                                  : erg::BackendKind::kAuto;
  cfg.progress_fd = flags.progress_fd;
  cfg.quiet = flags.quiet;
  return erg::run_job(cfg);
}
