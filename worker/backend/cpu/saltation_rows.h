// SPDX-License-Identifier: Apache-2.0
// The scatter of saltation (stages/saltation.h step 2) along one row on the
// CPU: the plain path, stages/hop_landing.h cell by cell, and the fast path
// of the expected mode without obstacles in reach, which computes every
// landing point and kernel split in a vectorised pass and adds them in a scalar one.
// tests/sim/test_cpu_fast_paths.cpp proves the two give the same bits.
#pragma once

#include <cstddef>

#include "core/grid.h"
#include "core/units.h"
#include "core/vec2.h"
#include "stages/hop_landing.h"

namespace erg::cpu {

// Plain path: each cell's airborne sand lands by land_hop into `landed`
// (storage of the whole padded tile), and the airborne buffer is emptied.
// h_base and o_base: the height and obstacle fields at local cell (0, 0),
// ghosts filled (the slope of the hop's deflection, the obstacle walk).
inline void scatter_row(units_t* air, const float* wx, const float* wy, const TileGeom& g, int y,
                        std::uint64_t seed, std::uint64_t step, const saltation::Params& p,
                        bool obstacles, const float* h_base, const float* o_base, units_t* landed) {
  units_t* base = landed + g.at(0, 0);
  const long pitch = g.pitch;
  for (int x = 0; x < g.nx; ++x) {
    const units_t a = air[x];
    if (a == 0) continue;
    air[x] = 0;
    const long c = static_cast<long>(y) * pitch + x;
    const saltation::Landing L =
        saltation::landing_over(x, y, {wx[x], wy[x]}, h_base + c, o_base + c, pitch, p);
    const saltation::LandingDraw u = p.stochastic
                                         ? saltation::landing_draw(seed, step, g.global_index(x, y))
                                         : saltation::LandingDraw{0.0f, 0.0f};
    saltation::land_hop(a, x, y, L, u, p, obstacles, o_base, pitch, [&](int cx, int cy, units_t q) {
      base[static_cast<long>(cy) * pitch + cx] += q;
    });
  }
}

// Fast path, expected mode without obstacles: where each cell's airborne sand
// lands (storage index of the first of the kernel's 3 x 3 receiving cells)
// and its exact nine-way split. Empties the airborne buffer (everything is in
// flight). Deflect: the hop turns down the slope of the heights `h` (row y,
// ghosts filled; no obstacles in reach, so the slope is the heights' own),
// as in the plain path.
template <bool Deflect>
inline void split_row(units_t* __restrict air, const float* __restrict wx,
                      const float* __restrict wy, const float* __restrict h, int nx, int y,
                      long origin, long pitch, const saltation::Params p, long* __restrict target,
                      units_t* __restrict parts) {
  // (Parameters by value: int64 stores could alias fields read through a
  // reference, which would block vectorisation.)
  for (int x = 0; x < nx; ++x) {
    const saltation::Landing L =
        Deflect ? saltation::deflected_landing(
                      x, y, {wx[x], wy[x]},
                      saltation::central_slope(h[x + 1], h[x - 1], h[x + pitch], h[x - pitch],
                                               p.cell_m),
                      p)
                : saltation::landing(x, y, {wx[x], wy[x]}, p);
    const saltation::Spread sx = saltation::spread(L.fx);
    const saltation::Spread sy = saltation::spread(L.fy);
    units_t q[saltation::kLandingCells];
    saltation::split_spread(air[x], sx, sy, q);
    target[x] = origin + static_cast<long>(L.y0 + sy.lo) * pitch + L.x0 + sx.lo;
    for (int k = 0; k < saltation::kLandingCells; ++k)
      parts[saltation::kLandingCells * x + k] = q[k];
    air[x] = 0;
  }
}
// The adds of split_row's parts (which may collide: scalar).
inline void add_splits(const long* target, const units_t* parts, int nx, long pitch,
                       units_t* landed) {
  for (int x = 0; x < nx; ++x) {
    const units_t* q = parts + saltation::kLandingCells * static_cast<std::size_t>(x);
    units_t* t = landed + target[x];
    for (int j = 0; j < 3; ++j, t += pitch, q += 3) {
      t[0] += q[0];
      t[1] += q[1];
      t[2] += q[2];
    }
  }
}

}  // namespace erg::cpu
