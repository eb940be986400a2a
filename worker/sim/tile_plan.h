// SPDX-License-Identifier: Apache-2.0
// The tile grid a job's domain gets on a number of ranks, without MPI or a
// simulation: erg-worker tiles with it (sim/tiling.h), ergd checks a job's
// rank count with it at submission. Library erg_tiling (the model constants,
// the decomposition): no backend, FFT or threads.
#pragma once

#include "dist/decomposition.h"
#include "erg/v1/job.pb.h"

namespace erg {

// The tile grid make_tiling chooses for `ranks` ranks (tiles_x, tiles_y > 0:
// the user's grid). Throws std::invalid_argument with the reason when no grid
// works.
dist::Decomposition plan_tiles(const erg::v1::JobSpec& spec, int ranks, int tiles_x = 0,
                               int tiles_y = 0);

}  // namespace erg
