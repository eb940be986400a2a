// SPDX-License-Identifier: Apache-2.0
// The lengths the model uses, in metres, against the grid that must resolve
// them (docs/physical-units.md, "Lengths on the grid").
//
// A job's lengths are physical: the hop (in the physical modes the
// saturation length's, model.deposit_on_sand x physics.saturation_length_m),
// the wind shadow's reach, the echo dunes' reach, the wind-warping smoothing
// and the shear-stress kernel. The stages turn each into cells in one of
// three ways, and each has its own rule for when the cells are too coarse:
//
//  - a hop lands on the 3 x 3 landing kernel (stages/saltation.h, spread()),
//    whose spread is 1/2 cell per axis whatever the hop: the hop is resolved
//    when that spread is at most a quarter of it, from 2 cells; a hop under
//    one cell is raised to one cell (physics::physical_hop_m);
//  - a reach marched in whole cells (the shadow's N_s = ceil(R_s / l), the
//    echo reach's, the shear kernel's radius in coarse cells) is lengthened
//    by the rounding by less than one cell: resolved when that is at most a
//    quarter of it, from 4 cells;
//  - the wind-warping Gaussians are sampled on cells of at most sigma / 4
//    (stages/wind_warping.h, coarse_factor): the smoothed slope's error is
//    then below (l / sigma)^2 / 6 = 1%; a cell wider than sigma / 4 cannot
//    keep that.
//
// One more rule is about the step, not a length: with the shear stress over
// relief (physical modes, physics.shear_stress_a > 0) a step lifts
// model.slab_m of sand, and above 1/40 of the cell the windward faces
// steepen and dunes calve and spread with the step, not with the physics;
// below it the speeds hardly change with the step, the shapes still do
// (docs/physical-units.md, "The step with the stress on").
//
// And one about the wind's clock: a bidirectional regime whose period_steps
// is shorter than 1 + flux_ratio cannot blow its secondary wind in every
// period (wind/regime.cpp gives the primary floor(k p N / (1 + N)) steps over
// the first k periods), so the winds alternate more slowly than the period
// says, though the flux ratio stays exact over the long run.
//
// The job still runs (these are warnings, not errors): `erg check`, the
// worker's start-up log and ergd's answer to a submitted job all say them,
// in these words.
#pragma once

#include <string>
#include <vector>

#include "erg/v1/job.pb.h"

namespace erg {

// Cells a hop must span: the landing kernel's spread (1/2 cell) is then at
// most a quarter of it.
inline constexpr double kHopResolvedCells = 2.0;
// Cells a reach marched in whole cells must span: rounding it up adds at
// most a quarter.
inline constexpr double kReachResolvedCells = 4.0;
// Cells per sigma of a wind-warping Gaussian (stages/wind_warping.h).
inline constexpr double kSigmaResolvedCells = 4.0;

// The largest model.slab_m per metre of cell at which, with the shear
// stress on, dunes no longer widen and calve with the step (measured).
inline constexpr double kSlabPerCellWithStress = 1.0 / 40.0;

// One length the grid does not resolve.
struct UnresolvedLength {
  std::string what;     // e.g. "saltation hop"
  std::string field;    // the parameter(s) it comes from
  double length_m = 0;  // the length the job asks for
  double cell_m = 0;    // the cells it is measured in (coarse cells for the shear kernel)
  double finest_m = 0;  // the largest domain.cell_size_m that resolves it
  std::string warning;  // the whole sentence: length, value, cell size, consequence
};

// Every length of a defaults-filled, validated job that its cells do not
// resolve; empty when all are resolved.
std::vector<UnresolvedLength> unresolved_lengths(const erg::v1::JobSpec& spec);

// The step's warning (see above), or "" when the step is fine.
std::string step_warning(const erg::v1::JobSpec& spec);

// The wind regimes' (the job's, then the events' in order) whose
// bidirectional period is too short for the secondary to blow in every
// period; empty when none is.
std::vector<std::string> wind_period_warnings(const erg::v1::JobSpec& spec);

// The warnings alone, the lengths', the step's, then the wind periods', one
// sentence each (without a "warning:" prefix).
std::vector<std::string> resolution_warnings(const erg::v1::JobSpec& spec);

}  // namespace erg
