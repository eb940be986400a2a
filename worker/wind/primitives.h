// SPDX-License-Identifier: Apache-2.0
// The local wind primitives active at a step ([P19] 4.4), resolved from the
// job: its own wind_primitives (steps from 0), plus those events add (steps
// from the event) minus those events remove, on the timeline order of
// events (step, then file order). Depends only on the spec and the step, so
// a restart or a steered run recomputes the same list.
#pragma once

#include <cstdint>
#include <vector>

#include "erg/v1/job.pb.h"
#include "stages/wind_primitives.h"

namespace erg::wind {

// Active primitives at `step`, with their envelopes folded in, in timeline
// order (the order their contributions are summed). Empty when none blows.
std::vector<wind_primitives::Primitive> primitives_at(const erg::v1::JobSpec& spec,
                                                      std::int64_t step);

// The same primitives in batches for the backends.
std::vector<wind_primitives::Batch> batches(const std::vector<wind_primitives::Primitive>& p);

// Envelope in [0, 1] of a primitive that took effect at `origin` (0 or its
// event's step), at `step`: 0 outside [start, end), smoothstep ramps of
// ramp_steps at both ends.
double envelope(const erg::v1::WindPrimitive& w, std::int64_t origin, std::int64_t step);

}  // namespace erg::wind
