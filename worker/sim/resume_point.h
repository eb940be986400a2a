// SPDX-License-Identifier: Apache-2.0
// Which checkpoint a resume continues from: the newest one in
// DIR/checkpoints that proves its integrity (io::read_checkpoint verifies its
// checksums) and whose spec agrees with the run's record, DIR/job.json.
//
// Agreement: with defaults filled on both sides, the two specs are equal
// except for run.steps, run.snapshot_every and run.checkpoint_every (what
// `--resume DIR --steps N` and the other overrides may change), and the
// checkpoint's events are a prefix of job.json's (events steered after it was
// written extend them, and the resumed run takes them, so the steps it redoes
// see those events at the steps they were steered at). A checkpoint that
// disagrees in anything else is refused, naming the first difference: it is
// not this run's state (a copied file, or a corruption its checksums did not
// cover), and continuing from it would be silently wrong.
#pragma once

#include <string>
#include <vector>

#include "erg/v1/job.pb.h"

namespace erg {

struct ResumePoint {
  std::string path;       // "" when no checkpoint qualifies
  std::int64_t step = 0;  // the checkpoint's step
  erg::v1::JobSpec spec;  // the checkpoint's spec, defaults filled, job.json's events adopted
  // Newer checkpoints passed over, each "step_N.h5: why", newest first.
  std::vector<std::string> skipped;
};

// Looks at DIR/checkpoints newest first (rank 0 alone; reads whole files).
// Never throws for a bad checkpoint: its reason goes to `skipped`.
ResumePoint choose_resume_point(const std::string& out_dir);

// "" when `checkpoint` may continue the run recorded as `recorded` (see
// above); otherwise the first difference, e.g. "model.warp_small_radius_m:
// 54 in the checkpoint, 50 in job.json". Both defaults-filled.
std::string spec_difference(const erg::v1::JobSpec& checkpoint, const erg::v1::JobSpec& recorded);

}  // namespace erg
