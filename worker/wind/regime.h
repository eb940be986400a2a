// SPDX-License-Identifier: Apache-2.0
// High-altitude wind a(t) ([P19] 4.1): the uniform wind above the terrain at
// each step, from the job's regime and the wind events of its timeline.
//
// A regime's own clock starts when it takes effect (step 0 for the job's
// regime, the event's step for a switched-in one): series keyframes and the
// bidirectional period count from there. Wind-rose draws depend only on
// (seed, step), so they are the same on every tiling and after a restart.
#pragma once

#include <cstdint>

#include "core/vec2.h"
#include "erg/v1/job.pb.h"

namespace erg::wind {

// Wind vector (m/s) of a regime, `local_step` steps after it took effect.
Vec2 regime_at(const erg::v1::WindRegime& regime, std::int64_t local_step, std::int64_t global_step,
               std::uint64_t seed);

// Wind at a step of the job: the last wind event at or before `step`, else
// the job's regime.
Vec2 at_step(const erg::v1::JobSpec& spec, std::int64_t step);

// The regime that blows at `step` (the one at_step draws from).
const erg::v1::WindRegime& regime_in_effect(const erg::v1::JobSpec& spec, std::int64_t step);

// Shear velocity u* (m/s) of the high-altitude wind at a step in the
// physical modes (wind/physics.h); 0 in model units.
double shear_velocity_at(const erg::v1::JobSpec& spec, std::int64_t step);

// Unit vector of a direction in degrees (counter-clockwise from +x).
Vec2 direction(double deg);

}  // namespace erg::wind
