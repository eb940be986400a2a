// SPDX-License-Identifier: Apache-2.0
// Echo dunes ([N24] 3.5 and 4.2.2, after Taylor and Keyser 2023 [TK23]): in
// front of a steep cliff facing the wind, the flow separates into a reverse
// eddy that keeps a sand-free gap at the cliff's foot and drops its sand
// further upwind, where an echo dune grows (wind tunnel experiments of Tsoar
// 1983, cited by [N24] and [TK23]).
//
// Each cell classifies itself (the reversed search of [N24] 4.2.2, free of
// races): it looks downwind, one cell length at a time with nearest-neighbour
// samples of the heights the wind sees ([N24] 3.5 keeps nearest neighbour for
// this search), for the first face rising faster than tan(cliff angle) per
// cell; the cliff's height H is the rise while the face stays that steep. A
// cell within gap_ratio * H of the cliff's foot is an *erosion* cell
// (r_e = -1), one within sticky_ratio * H a *sticky* cell (r_e = stickiness
// > 0), any other cell is neither (r_e = 0). Saltation then lifts
// eps (f + k_e) from erosion cells and eps f (1 - r_e) from sticky ones, and
// deposits nothing on erosion cells and beta + r_e (1 - beta) on sticky ones
// ([N24] 3.6: "multiplied by 0.5 if the cell is sticky and we add k_e = 1 if
// the cell is an erosion cell"). Cliffs are terrain (bedrock and sand):
// obstacle heights are taken out of the heights the wind sees, because sand
// stopped by an obstacle lands at its windward foot (stages/obstacles.h),
// which as an erosion cell would never let it settle; and a cell's search
// ends at the first obstacle downwind (a cliff behind it is hidden from the
// cell, and the foot of an obstacle must stay a place where sand settles).
#pragma once

#include "core/hd.h"
#include "core/vec2.h"

namespace erg::echo_dunes {

struct Params {
  bool on;
  int steps;            // cells searched downwind
  float rise_per_cell;  // tan(cliff angle) * l
  float cell_m;         // l
  float gap_ratio, sticky_ratio;
  float stickiness;
};

inline constexpr float kBlocked = 1.0e30f;

// r_e of local cell (x, y): -1 erosion, > 0 sticky, 0 neither. `h_base` is
// the halo-filled height field the wind sees and `o_base` the obstacle
// heights, both at local cell (0, 0). Sample offsets are
// rounded from the step alone, never from the cell's position, so every
// tiling samples the same cells.
ERG_HD float classify(const float* h_base, const float* o_base, long pitch, int x, int y, Vec2 w,
                      const Params& p) {
  const float speed = length(w);
  if (!p.on || !(speed > 0.0f) || p.steps <= 0) return 0.0f;
  const float ux = w.x / speed, uy = w.y / speed;
  // The terrain (without obstacles) j cells downwind; the search ends at an
  // obstacle (-kBlocked; see above).
  auto h = [&](int j) {
    const float fj = static_cast<float>(j);
    const int dx = static_cast<int>(floorf(fj * ux + 0.5f));
    const int dy = static_cast<int>(floorf(fj * uy + 0.5f));
    const long i = static_cast<long>(y + dy) * pitch + (x + dx);
    return o_base[i] > 0.0f ? -kBlocked : h_base[i] - o_base[i];
  };
  float prev = h(0);
  if (prev <= -kBlocked) return 0.0f;  // an obstacle holds no sand anyway
  for (int j = 1; j <= p.steps; ++j) {
    const float hj = h(j);
    if (hj <= -kBlocked) return 0.0f;
    if (hj - prev > p.rise_per_cell) {
      // The foot of the cliff is j - 1 cells downwind; climb while steep.
      const float foot = prev;
      float top = hj;
      for (int k = j + 1; k <= p.steps; ++k) {
        const float hk = h(k);
        if (!(hk - top > p.rise_per_cell)) break;
        top = hk;
      }
      const float height = top - foot;
      const float d_m = static_cast<float>(j - 1) * p.cell_m;  // to the foot
      return d_m < p.gap_ratio * height ? -1.0f
                                        : (d_m < p.sticky_ratio * height ? p.stickiness : 0.0f);
    }
    prev = hj;
  }
  return 0.0f;
}

}  // namespace erg::echo_dunes
