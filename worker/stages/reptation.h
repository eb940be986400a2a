// SPDX-License-Identifier: Apache-2.0
// Reptation ([N24] 3.7, eqs. 6-8): impacts push sand down every slope.
//
// Between neighbours i and j the flux is symmetric: with d the slope between
// them and s_r the impact strength from saltation,
//   s_m = k_r |d| (s_r(i) + s_r(j)) / 2,
// capped by the donor's (the higher cell's) sand, and each cell applies the
// mean over its 8 neighbours. Donor and receiver evaluate transfer() with the
// same arguments in the same order, so both get the same integer count: a
// gather with no atomics, exact to the unit. The 1/8 is taken in integers on
// the donor's sand, so 8 transfers never exceed it (the reference code's
// flaw, docs/design.md "Defects avoided").
#pragma once

#include "core/hd.h"
#include "core/units.h"

namespace erg::reptation {

// Units moving from donor to receiver. dh = h_donor - h_receiver >= 0 units;
// dist_m = l |i - j|. The impact strengths enter as a sum, and float addition
// is commutative, so their order does not matter.
ERG_HD units_t transfer(units_t dh, float dist_m, float sr_donor, float sr_receiver,
                        units_t sand_donor, float k_r) {
  const float slope = units_to_m(dh) / dist_m;                              // eq. 6
  const float s_m = k_r * slope * (0.5f * (sr_donor + sr_receiver));        // eq. 7
  const units_t per_neighbour = floor_units(s_m * (0.125f * kUnitsPerMf));  // mean of 8
  return min_of(per_neighbour, sand_donor >> 3);                            // eq. 8
}

// Signed change of cell i from its exchange with neighbour j (heights h,
// impact strengths sr, sand s). exchange(i, j) == -exchange(j, i) exactly:
// the higher cell donates, and both evaluate the same transfer.
ERG_HD units_t exchange(units_t h_i, units_t h_j, float sr_i, float sr_j, units_t s_i, units_t s_j,
                        float dist_m, float k_r) {
  const units_t dh = h_i - h_j;
  const units_t t = transfer(dh < 0 ? -dh : dh, dist_m, sr_i, sr_j, dh > 0 ? s_i : s_j, k_r);
  return dh > 0 ? -t : t;  // dh == 0 gives t == 0
}

// exchange() between cells that may be obstacles (o > 0, stages/obstacles.h):
// nothing moves into or out of an obstacle [BR04 4.2]. Symmetric like
// exchange(), so donor and receiver still agree to the unit.
ERG_HD units_t exchange_free(units_t h_i, units_t h_j, float sr_i, float sr_j, units_t s_i,
                             units_t s_j, float dist_m, float k_r, float o_i, float o_j) {
  const units_t t = exchange(h_i, h_j, sr_i, sr_j, s_i, s_j, dist_m, k_r);
  return (o_i > 0.0f) | (o_j > 0.0f) ? 0 : t;
}

}  // namespace erg::reptation
