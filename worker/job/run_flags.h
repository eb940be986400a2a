// SPDX-License-Identifier: Apache-2.0
// The command-line flags of a run, parsed in one place for `erg run`,
// `erg-worker` (and, later, `erg submit`): --steps, --snapshot-every,
// --checkpoint-every, --threads, --backend, --out, --resume, --ranks, --tiles,
// and erg-worker's own --progress-fd and --steer-dir.
#pragma once

#include <string>
#include <vector>

#include "job/spec.h"

namespace erg::job {

struct RunFlags {
  std::string job_path;    // positional
  std::string out_dir;     // --out DIR
  std::string resume_dir;  // --resume DIR
  Overrides overrides;
  int threads = 0;               // --threads T; unset (0): all hardware threads
  std::string backend = "auto";  // --backend auto|cpu|cuda
  int ranks = 0;                 // --ranks P (erg run starts P MPI ranks)
  std::string tiles;             // --tiles PXxPY (the tile grid; default: chosen)
  int progress_fd = -1;          // --progress-fd FD (erg-worker only)
  std::string steer_dir;         // --steer-dir DIR (erg-worker only): events to apply
  bool quiet = false;            // --quiet
};

// Parses args (without the program name); throws std::invalid_argument with
// one clear line naming the flag on a bad flag or value.
RunFlags parse_run_flags(const std::vector<std::string>& args);

// Usage text of the flags above.
std::string run_flags_usage();

}  // namespace erg::job
