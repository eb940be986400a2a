// SPDX-License-Identifier: Apache-2.0
#include "job/run_flags.h"

#include <stdexcept>

namespace erg::job {

namespace {
long long parse_count(const std::string& flag, const std::string& v, long long lo, long long hi) {
  size_t used = 0;
  long long x = 0;
  try {
    x = std::stoll(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != v.size() || v.empty() || x < lo || x > hi)
    throw std::invalid_argument(flag + " " + v + ": expected an integer in [" + std::to_string(lo) +
                                ", " + std::to_string(hi) + "]");
  return x;
}
}  // namespace

RunFlags parse_run_flags(const std::vector<std::string>& args) {
  RunFlags f;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw std::invalid_argument(a + ": missing value");
      return args[++i];
    };
    if (a == "--out")
      f.out_dir = value();
    else if (a == "--resume")
      f.resume_dir = value();
    else if (a == "--steps")
      f.overrides.steps = parse_count(a, value(), 0, 1000000000);
    else if (a == "--snapshot-every")
      f.overrides.snapshot_every = parse_count(a, value(), 0, 1000000000);
    else if (a == "--checkpoint-every")
      f.overrides.checkpoint_every = parse_count(a, value(), 0, 1000000000);
    else if (a == "--threads")
      f.threads = static_cast<int>(parse_count(a, value(), 1, 4096));
    else if (a == "--progress-fd")
      f.progress_fd = static_cast<int>(parse_count(a, value(), 0, 65535));
    else if (a == "--steer-dir") {
      f.steer_dir = value();
      if (f.steer_dir.empty()) throw std::invalid_argument("--steer-dir: expected a directory");
    } else if (a == "--quiet")
      f.quiet = true;
    else if (a == "--ranks")
      f.ranks = static_cast<int>(parse_count(a, value(), 1, 4096));
    else if (a == "--tiles")
      f.tiles = value();
    else if (a == "--backend") {
      f.backend = value();
      if (f.backend != "auto" && f.backend != "cpu" && f.backend != "cuda")
        throw std::invalid_argument("--backend " + f.backend + ": expected auto, cpu or cuda");
    } else if (!a.empty() && a[0] == '-') {
      throw std::invalid_argument(a + ": unknown flag\n" + run_flags_usage());
    } else if (f.job_path.empty()) {
      f.job_path = a;
    } else {
      throw std::invalid_argument(a + ": unexpected argument (the job file is " + f.job_path + ")");
    }
  }
  if (!f.resume_dir.empty()) {
    if (!f.job_path.empty())
      throw std::invalid_argument(
          "--resume DIR continues the run in DIR with its own job; give no job file");
    if (!f.out_dir.empty() && f.out_dir != f.resume_dir)
      throw std::invalid_argument(
          "--resume DIR writes into DIR; --out must be omitted or the same");
    f.out_dir = f.resume_dir;
  } else {
    if (f.job_path.empty())
      throw std::invalid_argument("missing the job file (JOB.json)\n" + run_flags_usage());
    if (f.out_dir.empty()) throw std::invalid_argument("missing --out DIR\n" + run_flags_usage());
  }
  return f;
}

std::string run_flags_usage() {
  return "usage: erg run JOB.json --out DIR [--steps N] [--snapshot-every K]\n"
         "               [--checkpoint-every C] [--threads T] [--backend auto|cpu|cuda]\n"
         "               [--ranks P] [--tiles PXxPY]\n"
         "       erg run --resume DIR [--steps N] [...]\n"
         "       erg-worker JOB.json --out DIR [...] (the same flags)\n"
         "       erg-worker --resume DIR [...]\n"
         "erg-worker only: [--progress-fd FD] (erg.v1.WorkerEvent JSON lines) [--quiet]\n"
         "                 [--steer-dir DIR] (apply DIR/*.json, one erg.v1.Event each, at the\n"
         "                 next step boundary; renamed .applied or .rejected)";
}

}  // namespace erg::job
