// SPDX-License-Identifier: Apache-2.0
// Saltation with abrasion ([P19] 5.1-5.2, [N24] 3.6), per cell.
//
// Each step: (1) lift sand into the airborne slab buffer; (2) advect every
// airborne amount one hop downwind, split over the 3 x 3 cells around the
// landing point by a kernel of the same spread at every wind angle (spread()) (a scatter of integer
// units: any order gives the same sums; ghost contributions are added back to their owners); (3) at
// each cell a fraction beta of what landed is deposited and the rest bounces and stays airborne for
// the next step; bounces over thin sand abrade bedrock into sand. What landed drives reptation.
//
// Two transport modes share these functions: EXPECTED moves the expected
// value of every event [N24]; STOCHASTIC moves whole slabs with the
// probabilities of [P19]/[W95], drawn from core/philox.h.
#pragma once

#include "core/hd.h"
#include "core/units.h"
#include "core/vec2.h"
#include "stages/vegetation.h"

namespace erg::saltation {

struct Params {
  float slab_units;  // eps_S in units
  float hop_time_s;  // hop length = |w| hop_time_s ...
  float max_hop_m;   // ... capped here
  float cell_m;
  float deposit_on_sand;       // f_S(s > 0)
  float deposit_on_bedrock;    // f_S(0)
  float abrasion_k;            // k_a
  units_t abrasion_threshold;  // sand thinner than this is abraded through
  bool stochastic;
  float erosion_k;  // k_e of echo-dune erosion cells (stages/echo_dunes.h)
  // Physical modes (wind/physics.h; 0 in model units): the local shear
  // velocity is |w| * ustar_per_mps; the lift follows the flux law's shape
  // above the threshold ustar_t, normalised to 1 at the reference u*.
  float ustar_per_mps;
  float ustar_t;
  float inv_reference_shape;  // 1 / flux_shape(reference u*)
  bool kawamura;              // flux law: Kawamura 1951, else Lettau & Lettau 1978
  // k of the hop's deflection down the slope (physics.hop_slope_deflection;
  // landing() below); 0 in model units and when off.
  float slope_k;
};

// How much of a slab a cell lifts for its surface wind: 1 in model units;
// in the physical modes the saturated flux law's dependence on the local u*
// relative to the reference u* (Lettau & Lettau 1978 u*^2 (u* - u_t), or
// Kawamura 1951 (u* - u_t)(u* + u_t)^2), and 0 at or below the fluid
// threshold u_t of Bagnold 1941: below it the wind lifts nothing. With the
// hop of a fixed length (landing() below) the flux over flat sand is then
// proportional to the law (Owen 1964: the mass in saltation grows with the
// excess shear; Creyssels et al. 2009: hop lengths do not depend on u*).
ERG_HD float transport_factor(float wind_speed, const Params& p) {
  const float u = wind_speed * p.ustar_per_mps;
  const float e = max_of(u - p.ustar_t, 0.0f);
  const float up = u + p.ustar_t;
  const float shape = p.kawamura ? e * up * up : u * u * e;
  return p.ustar_per_mps > 0.0f ? shape * p.inv_reference_shape : 1.0f;
}

// The lift factor (1 - sigma)(1 - v) with the echo-dune classification r_e
// (stages/echo_dunes.h): + k_e on erosion cells (r_e < 0), x (1 - r_e) on
// sticky ones [N24 3.6]. r_e = 0 leaves it unchanged, bit for bit.
ERG_HD float echo_lift_factor(float f, float echo, const Params& p) {
  return echo < 0.0f ? f + p.erosion_k : (echo > 0.0f ? f * (1.0f - echo) : f);
}
// Deposition with r_e: none on erosion cells, beta + r_e (1 - beta) on sticky ones.
ERG_HD float echo_deposition(float beta, float echo) {
  return echo < 0.0f ? 0.0f : (echo > 0.0f ? beta + echo * (1.0f - beta) : beta);
}

// (1) Lift: eps_S (1 - sigma)(1 - v), at most the sand present [N24 eq. 5].
// Still air lifts nothing (a hop of length 0 would only churn the cell).
// Times transport_factor (1 in model units, so the product is exact).
ERG_HD units_t lift_expected(units_t sand, float shadow, float v, float wind_speed, const Params& p,
                             float echo = 0.0f) {
  const units_t want =
      floor_units(p.slab_units * (echo_lift_factor(vegetation::lift_factor(shadow, v), echo, p) *
                                  transport_factor(wind_speed, p)));
  return wind_speed > 0.0f ? min_of(want, sand) : 0;
}
// A whole slab is lifted with probability (1 - sigma)(1 - v) [P19 5.1].
// (An erosion cell's factor above 1 lifts a second slab: floor of the factor
// slabs surely, one more with its fractional part.)
ERG_HD units_t lift_stochastic(units_t sand, float shadow, float v, float wind_speed, float u,
                               const Params& p, float echo = 0.0f) {
  const float f = echo_lift_factor(vegetation::lift_factor(shadow, v), echo, p) *
                  transport_factor(wind_speed, p);
  const float whole = floorf(f);
  const float slabs = wind_speed > 0.0f ? whole + (u < f - whole ? 1.0f : 0.0f) : 0.0f;
  return min_of(floor_units(p.slab_units * slabs), sand);
}

// (2) Landing point of an amount leaving local cell (x, y) under wind w, in
// local cell coordinates: one hop of |w| hop_time_s metres, at most max_hop_m;
// in the physical modes always max_hop_m (d0 of [P19 5.1]), the direction
// from w (hop lengths do not depend on u*: Creyssels et al. 2009).
struct Landing {
  int x0, y0;    // the cell the landing point is in
  float fx, fy;  // the landing point's fraction past x0, y0 (spread())
};
ERG_HD float hop_length_m(float wind_speed, const Params& p) {
  return p.ustar_per_mps > 0.0f ? p.max_hop_m : min_of(wind_speed * p.hop_time_s, p.max_hop_m);
}
// A hop of hop_m metres along d (of length d_len; none when 0).
ERG_HD Landing land_along(int x, int y, Vec2 d, float d_len, float hop_m, const Params& p) {
  const bool moving = d_len > 0.0f;  // (selects, no branch: loops vectorise)
  const float scale = moving ? hop_m / ((moving ? d_len : 1.0f) * p.cell_m) : 0.0f;
  // The hop is split into whole cells and a fraction on its own (not added
  // to the cell's coordinate in floating point), so the split does not
  // depend on where the tile starts: the same on every tiling.
  const float dx = d.x * scale, dy = d.y * scale;
  const float fx = floorf(dx), fy = floorf(dy);
  return {x + static_cast<int>(fx), y + static_cast<int>(fy), dx - fx, dy - fy};
}
ERG_HD Landing landing(int x, int y, Vec2 w, const Params& p) {
  const float speed = length(w);
  return land_along(x, y, w, speed, hop_length_m(speed, p), p);
}

// The slope of a cell from its four neighbours' heights (metres): central
// differences, east minus west and north minus south over two cells.
ERG_HD Vec2 central_slope(float e, float w, float n, float s, float cell_m) {
  const float inv_2l = 0.5f / cell_m;
  return {(e - w) * inv_2l, (n - s) * inv_2l};
}

// The slope a grain hops over: central_slope() of the ground height
// (bedrock + sand, metres; `h` points at the cell in the height field, whose
// ghosts the step has filled, `o` at the same cell of the obstacles). An
// obstacle next to the cell counts as level with it: a wall stops a hop
// (stages/obstacles.h), it does not tilt the bed under it.
ERG_HD Vec2 ground_slope(const float* h, const float* o, long pitch, float cell_m) {
  const float c = h[0];
  const float e = o[1] > 0.0f ? c : h[1], w = o[-1] > 0.0f ? c : h[-1];
  const float n = o[pitch] > 0.0f ? c : h[pitch], s = o[-pitch] > 0.0f ? c : h[-pitch];
  return central_slope(e, w, n, s, cell_m);
}
// With the deflection on (p.slope_k > 0), gravity turns the hop down the
// slope: it goes along w / |w| - k grad h (Sauermann, Kroy & Herrmann 2001,
// the grains' momentum balance linearised about a grain moving downwind;
// physics.hop_slope_deflection), with the hop's length kept. On a barchan's
// flanks that carries sand away from the axis, the outward flux that
// stretches the horns. Only for k > 0: w / |w| is not w's own bits, so
// landing_over() picks landing() when the deflection is off.
ERG_HD Landing deflected_landing(int x, int y, Vec2 w, Vec2 slope, const Params& p) {
  const float speed = length(w);
  const Vec2 d = speed > 0.0f ? (1.0f / speed) * w - p.slope_k * slope : Vec2{};
  return land_along(x, y, d, length(d), hop_length_m(speed, p), p);
}
// The landing of sand leaving local cell (x, y) under wind w, over the ground
// at h and o (ground_slope()'s pointers): deflected down its slope when
// p.slope_k > 0, else landing()'s bits (the slope is then not read). Both
// backends' scatters call this.
ERG_HD Landing landing_over(int x, int y, Vec2 w, const float* h, const float* o, long pitch,
                            const Params& p) {
  return p.slope_k > 0.0f ? deflected_landing(x, y, w, ground_slope(h, o, pitch, p.cell_m), p)
                          : landing(x, y, w, p);
}

// The landing kernel: where around the landing point (x0 + fx, y0 + fy) a
// hop's sand comes down. Per axis, three cells centred on the cell nearest
// to the landing point, with weights whose mean is the landing point and
// whose variance is `var` (cells^2) whatever the fraction f; the two axes
// are independent, so the kernel's covariance is var * I: the same at every
// angle of the wind to the grid. (The bilinear split it replaces has the
// variance f (1 - f) per axis: 0 when a hop ends on a cell row, 1/4 halfway,
// so the lattice diffused sand across the wind by an amount set by the
// wind's angle to the grid; docs/dune-forms.md.) Mean and variance fix the
// three weights: w(-1) = (s - m) / 2, w(0) = 1 - s, w(+1) = (s + m) / 2 with
// m the offset from the nearest cell (|m| <= 1/2) and s = var + m^2; all
// are >= 0 for 1/4 <= var <= 3/4 (1/4: the smallest that the lattice
// allows at every fraction, the bilinear split's at f = 1/2).
constexpr int kLandingCells = 9;      // 3 x 3
constexpr float kLandingVar = 0.25f;  // cells^2 per axis: the smallest the lattice allows
struct Spread {
  int lo;      // first of the three cells, relative to x0 (-1 or 0)
  float w[3];  // weights of cells lo, lo + 1, lo + 2; they sum to 1
};
ERG_HD Spread spread(float f, float var = kLandingVar) {
  const bool up = f >= 0.5f;
  const float m = up ? f - 1.0f : f;  // from the nearest cell, in [-1/2, 1/2)
  const float s = var + m * m;        // E[offset^2] about the nearest cell
  // (Clamped at 0: at |m| = 1/2 and var = 1/4 rounding may leave -1e-8.)
  return {up ? 0 : -1,
          {max_of(0.5f * (s - m), 0.0f), max_of(1.0f - s, 0.0f), max_of(0.5f * (s + m), 0.0f)}};
}
// Exact split of `a` units over the 3 x 3 cells of the kernel: q[i + 3 j]
// for cell (x0 + sx.lo + i, y0 + sy.lo + j); the parts sum to a and are
// never negative (the rounding's remainder goes to the centre).
ERG_HD void split_spread(units_t a, const Spread& sx, const Spread& sy, units_t q[kLandingCells]) {
  const float af = static_cast<float>(a);
  units_t rest = a;
  for (int k = 0; k < kLandingCells; ++k) {
    if (k == 4) continue;
    q[k] = min_of(floor_units(af * (sx.w[k % 3] * sy.w[k / 3])), rest);
    rest -= q[k];
  }
  q[4] = rest;
}
// Stochastic: the whole amount lands in one cell, drawn per axis with the
// kernel's weights as probabilities (u: one uniform draw per axis).
ERG_HD int pick_spread(const Spread& s, float u) {
  return s.lo + (u < s.w[0] ? 0 : (u < s.w[0] + s.w[1] ? 1 : 2));
}

// (3) Deposition, bounce and abrasion at a cell where `landed` units arrived.
struct Impact {
  units_t deposited;  // to the cell's sand
  units_t bounced;    // stays airborne
  units_t abraded;    // bedrock turned into sand at this cell
  float reptation_m;  // s_r: sand that hit the cell, weighted by (1 - v) [N24 3.6]
};
// `sand` is the cell's sand after lifting; `u` the deposit draw (stochastic).
ERG_HD Impact impact(units_t landed, units_t sand, float shadow, float v, float resistance,
                     float wind_speed, float u, const Params& p, float echo = 0.0f) {
  // Branch-free (selects only), so the loop over cells vectorises.
  // Stochastic slabs see Werner's step (any sand); expected transport its mean.
  // (The division is not conditional: a conditional one is not if-converted.)
  const bool has_slab = p.slab_units > 0.0f;
  const float ramp = min_of(static_cast<float>(sand) / (has_slab ? p.slab_units : 1.0f), 1.0f);
  const float sand_fraction = (p.stochastic || !has_slab) ? (sand > 0 ? 1.0f : 0.0f) : ramp;
  const float beta =
      echo_deposition(vegetation::deposition_probability(shadow, sand_fraction, v,
                                                         p.deposit_on_sand, p.deposit_on_bedrock),
                      echo);
  const units_t expected = min_of(floor_units(static_cast<float>(landed) * beta), landed);
  Impact r;
  r.deposited = p.stochastic ? ((u < beta) ? landed : 0) : expected;
  r.bounced = landed - r.deposited;
  // Abrasion [P19 5.2]: k_a (1 - r) |w| (1 - v) per metre of sand bouncing on
  // thin sand (scaled by the bounced amount, [N24] 3.6).
  // (The condition selects the rate, not the conversion: a conditional
  // float-to-integer conversion is not if-converted, and blocks vectorising.)
  const bool abrades = (p.abrasion_k > 0.0f) & (r.bounced > 0) & (sand < p.abrasion_threshold);
  const float eps =
      abrades ? p.abrasion_k * (1.0f - resistance) * wind_speed * vegetation::abrasion_factor(v)
              : 0.0f;
  r.abraded = floor_units(eps * static_cast<float>(r.bounced));
  r.reptation_m = units_to_m(landed) * vegetation::reptation_factor(v);
  return r;
}

// Applies an impact to the cell's layers and buffers; returns the bedrock
// abraded (units), 0 when none.
ERG_HD units_t settle(const Impact& im, units_t& sand, units_t& bedrock, units_t& airborne,
                      float& reptation_m, units_t& deposited) {
  sand += im.deposited + im.abraded;
  bedrock -= im.abraded;
  airborne = im.bounced;
  reptation_m = im.reptation_m;
  deposited = im.deposited;
  return im.abraded;
}

}  // namespace erg::saltation
