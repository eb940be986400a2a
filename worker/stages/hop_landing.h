// SPDX-License-Identifier: Apache-2.0
// Where one cell's airborne sand lands (stages/saltation.h step 2), with or
// without obstacles in reach (stages/obstacles.h, [BR04 4.1]), for both
// transport modes: the one body the CPU and the GPU backends run per cell.
#pragma once

#include "core/hd.h"
#include "core/philox.h"
#include "core/units.h"
#include "stages/obstacles.h"
#include "stages/saltation.h"

namespace erg::saltation {

// The draws of the stochastic mode's receiving cell, one per axis: the
// landing stream of the source cell (core/philox.h), so every tiling draws
// the same.
struct LandingDraw {
  float x, y;
};
ERG_HD LandingDraw landing_draw(std::uint64_t seed, std::uint64_t step, std::uint64_t global_cell) {
  const auto r = random4(seed, step, global_cell, RandomStream::kLanding);
  return {u01(r.v[0]), u01(r.v[1])};
}

// Lands `a` units hopping from local cell (x, y) to `L`: calls add(cx, cy, q)
// for each receiving cell (local coordinates, ghosts included) and its part
// q; the parts sum to a. EXPECTED splits over the 3 x 3 cells of the landing
// kernel (spread()), STOCHASTIC puts the whole amount in the cell drawn with
// u from the same weights. With `obstacles`, the hop walks its path over
// o_base (local cell (0, 0), row pitch `pitch`) and a part meant for an
// obstacle, or past a blocked path, lands at the path's end instead. Adds
// are of integers: any order of them gives the same sums.
template <class Add>
ERG_HD void land_hop(units_t a, int x, int y, const Landing& L, LandingDraw u, const Params& p,
                     bool obstacles, const float* o_base, long pitch, Add&& add) {
  obstacles::Path path{false, x, y};
  if (obstacles)
    path = obstacles::hop_path(o_base, pitch, x, y, static_cast<float>(L.x0 - x) + L.fx,
                               static_cast<float>(L.y0 - y) + L.fy);
  const Spread sx = spread(L.fx), sy = spread(L.fy);
  const auto put = [&](int i, int j, units_t q) {
    obstacles::Cell c{L.x0 + i, L.y0 + j};
    if (obstacles) c = obstacles::receiver(o_base, pitch, c.x, c.y, path);
    add(c.x, c.y, q);
  };
  if (p.stochastic) {
    put(pick_spread(sx, u.x), pick_spread(sy, u.y), a);
  } else {
    units_t q[kLandingCells];
    split_spread(a, sx, sy, q);
    for (int k = 0; k < kLandingCells; ++k)
      if (q[k] != 0) put(sx.lo + k % 3, sy.lo + k / 3, q[k]);
  }
}

}  // namespace erg::saltation
