// SPDX-License-Identifier: Apache-2.0
// Avalanching ([N24] 3.8, eqs. 9-11), sand and bedrock.
//
// In each iteration every cell i computes, for its 8 neighbours j, the height
// above the angle of repose
//   B(i, j) = max(h(i) - h(j) - tan(theta_r) l |i - j|, 0)            (eq. 9)
// and moves B_A = min(B_max / (1 + B_max / B_sum), s(i))  (eq. 11) in total,
// to neighbour j in proportion p(i, j) = B(i, j) / B_sum, scaled by k_c.
//
// Exactness (docs/design.md, "Exactness"): the iteration is two gather passes over
// double-buffered fields, never in place. Pass 1: each donor i stores
// f(i) = k_c B_A / B_sum and the integer total it sends,
// out(i) = sum_j floor(f(i) B(i, j)). Pass 2: each receiver j recomputes
// floor(f(i) B(i, j)) with the same function and inputs as the donor did, so
// both agree to the unit; s'(j) = s(j) - out(j) + sum_i in(i -> j).
//
// Heights are float metres derived from the exact integers; tan_l(i) is
// tan(theta_r(i)) * l, with theta_r from the cell's vegetation.
//
// Isotropic repose (model.repose ISOTROPIC; NEIGHBOUR_PAIRS, [N24]'s, is the
// default: see job.proto for why). Comparing each
// neighbour pair with tan(theta_r) l |i - j| holds a plane of slope g facing
// phi where g max(cos phi, cos(phi - 45 deg)) <= tan(theta_r): the steepest
// pair of a plane is the lattice direction nearest its fall line, so slopes
// stand at 33 deg facing an axis or a diagonal and up to 35.1 deg facing
// 22.5 deg (docs/dune-forms.md, "Isotropy"). The angle of repose is a bound
// on the surface's own slope, |grad h| <= tan(theta_r) (Bagnold 1941 ch. 13;
// the continuum avalanche of Bouchaud et al. 1994), so each donor's tangent
// is scaled by that same factor, facing(), for its own fall line; then
// a plane of slope g exceeds repose in some pair exactly when g > tan
// theta_r, whatever its direction. The fall line is the Sobel gradient of
// the donor's 3 x 3 heights (the 8 neighbours eq. 9 reads already), so a
// receiver uses the tangent its donor computed from the same heights (the
// CPU keeps it per cell from pass 1; the GPU recomputes it) and both sides
// still agree to the unit.
#pragma once

#include "core/grid.h"
#include "core/hd.h"
#include "core/units.h"

namespace erg::avalanching {

// Eq. 9 with the distance factor folded in: metres above repose.
ERG_HD float excess(float h_donor, float h_receiver, float tan_l_donor, float dist_cells) {
  return max_of(h_donor - h_receiver - tan_l_donor * dist_cells, 0.0f);
}

// max(cos phi, cos(phi - 45 deg)) for the fall line phi of the 3 x 3 heights
// around a cell (kNeighbours order: E, NE, N, NW, W, SW, S, SE), from the
// Sobel gradient (gx, gy): with a = |gx|, b = |gy|, cos phi = max(a, b) / |g|
// and cos(phi - 45 deg) = (a + b) / (sqrt 2 |g|). 1 on flat ground. In
// [cos 22.5 deg, 1].
ERG_HD float facing(const float hn[8]) {
  const float gx = (2.0f * (hn[0] - hn[4]) + (hn[1] - hn[3])) + (hn[7] - hn[5]);
  const float gy = (2.0f * (hn[2] - hn[6]) + (hn[1] - hn[7])) + (hn[3] - hn[5]);
  const float a = fabsf(gx), b = fabsf(gy);
  const float g = sqrtf(a * a + b * b);
  return g > 0.0f ? max_of(max_of(a, b), (a + b) * 0.707106781f) / g : 1.0f;
}

// A donor's tangent: tan_l, scaled by facing() when the repose is isotropic.
ERG_HD float donor_tangent(float tan_l, const float hn[8], bool isotropic) {
  return isotropic ? tan_l * facing(hn) : tan_l;
}

// The integer units a donor with fraction f sends for an excess b (metres).
ERG_HD units_t transfer(float f, float b) {
  return floor_units(f * b * kUnitsPerMf);
}

// k_c schedule [N24 5]: damped every 10th iteration and the last five
// (iterations numbered from 1).
ERG_HD float kc_for(int iteration, int iterations, float kc, float kc_damped) {
  return (iteration % 10 == 0 || iteration > iterations - 5) ? kc_damped : kc;
}

// The excesses of eq. 9 over the 8 neighbours (kNeighbours order: straight,
// diagonal, alternating), written out so that compilers vectorise the loop
// over cells around them.
struct Excess {
  float b[8];
};
ERG_HD Excess excesses(float h, const float hn[8], float tan_l) {
  return {{excess(h, hn[0], tan_l, 1.0f), excess(h, hn[1], tan_l, kSqrt2),
           excess(h, hn[2], tan_l, 1.0f), excess(h, hn[3], tan_l, kSqrt2),
           excess(h, hn[4], tan_l, 1.0f), excess(h, hn[5], tan_l, kSqrt2),
           excess(h, hn[6], tan_l, 1.0f), excess(h, hn[7], tan_l, kSqrt2)}};
}

// The total a donor with fraction f sends: the sum of the shares its
// receivers compute with inflow().
ERG_HD units_t outflow(float f, const Excess& e) {
  return transfer(f, e.b[0]) + transfer(f, e.b[1]) + transfer(f, e.b[2]) + transfer(f, e.b[3]) +
         transfer(f, e.b[4]) + transfer(f, e.b[5]) + transfer(f, e.b[6]) + transfer(f, e.b[7]);
}

// Pass 1 at one cell, common path: the fraction f = k_c B_A / B_sum of eq. 11
// (0 when nothing exceeds repose or nothing is available). `check` is set when
// the shares might add up to more than is available; donor() then decides.
struct Fraction {
  float f;
  bool check;
};
ERG_HD Fraction fraction(float h, const float hn[8], float tan_l, units_t available, float kc) {
  const Excess e = excesses(h, hn, tan_l);
  const float bsum =
      ((((((e.b[0] + e.b[1]) + e.b[2]) + e.b[3]) + e.b[4]) + e.b[5]) + e.b[6]) + e.b[7];
  const float bmax = max_of(max_of(max_of(e.b[0], e.b[1]), max_of(e.b[2], e.b[3])),
                            max_of(max_of(e.b[4], e.b[5]), max_of(e.b[6], e.b[7])));
  const bool moves = bsum > 0.0f && available > 0;
  const float safe_sum = moves ? bsum : 1.0f;
  const float ba = min_of(bmax / (1.0f + bmax / safe_sum), units_to_m(available));  // eq. 11
  const float f = moves ? kc * ba / safe_sum : 0.0f;
  // The shares sum to at most k_c B_A (1 + 2^-19) in units (float rounding of
  // the 8 products and of the sums); with a 1e-4 margin they surely fit.
  const bool fits = kc * ba * kUnitsPerMf * 1.0001f < static_cast<float>(available);
  return {f, moves && !fits};
}

struct Donor {
  float f;      // fraction of each excess that is sent (0: sends nothing)
  units_t out;  // total units sent
  bool stuck;   // has excess, but every share rounds to 0 units
};

// Pass 1 at one cell, complete: float rounding can push the sum of shares a
// few units past what is available, then f shrinks until it fits (rare, and
// the same everywhere); a donor whose shares all round to 0 sends nothing and
// is marked stuck (a larger k_c may move it later). Where fraction() needs no
// check, its f sends exactly the same shares as donor()'s.
ERG_HD Donor donor(float h, const float hn[8], float tan_l, units_t available, float kc) {
  const Excess e = excesses(h, hn, tan_l);
  Donor d{fraction(h, hn, tan_l, available, kc).f, 0, false};
  d.out = outflow(d.f, e);
  while (d.out > available) {
    d.f *= 0.99999f;
    d.out = outflow(d.f, e);
  }
  if (d.out == 0) {
    d.stuck = d.f > 0.0f;
    d.f = 0.0f;
  }
  return d;
}

// Pass 2 at a receiver: units arriving from a donor with fraction f_donor.
ERG_HD units_t inflow(float f_donor, float h_donor, float h_receiver, float tan_l_donor,
                      float dist_cells) {
  return transfer(f_donor, excess(h_donor, h_receiver, tan_l_donor, dist_cells));
}

}  // namespace erg::avalanching
