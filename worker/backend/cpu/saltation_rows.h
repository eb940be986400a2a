// SPDX-License-Identifier: Apache-2.0
// The scatter of saltation (stages/saltation.h step 2) along one row on the
// CPU: the plain path, stages/hop_landing.h cell by cell, and the fast path
// of the expected mode without obstacles in reach, which computes every
// landing point and split in a vectorised pass and adds them in a scalar one.
// tests/sim/test_cpu_fast_paths.cpp proves the two give the same bits.
#pragma once

#include <cstddef>

#include "core/grid.h"
#include "core/units.h"
#include "stages/hop_landing.h"

namespace erg::cpu {

// Plain path: each cell's airborne sand lands by land_hop into `landed`
// (storage of the whole padded tile), and the airborne buffer is emptied.
inline void scatter_row(units_t* air, const float* wx, const float* wy, const TileGeom& g, int y,
                        std::uint64_t seed, std::uint64_t step, const saltation::Params& p,
                        bool obstacles, const float* o_base, units_t* landed) {
  units_t* base = landed + g.at(0, 0);
  const long pitch = g.pitch;
  for (int x = 0; x < g.nx; ++x) {
    const units_t a = air[x];
    if (a == 0) continue;
    air[x] = 0;
    const saltation::Landing L = saltation::landing(x, y, {wx[x], wy[x]}, p);
    const float u = p.stochastic ? saltation::landing_draw(seed, step, g.global_index(x, y)) : 0.0f;
    saltation::land_hop(a, x, y, L, u, p, obstacles, o_base, pitch, [&](int cx, int cy, units_t q) {
      base[static_cast<long>(cy) * pitch + cx] += q;
    });
  }
}

// Fast path, expected mode without obstacles: where each cell's airborne sand
// lands (storage index of the lower-left receiving cell) and its exact
// four-way split. Empties the airborne buffer (everything is in flight).
inline void split_row(units_t* __restrict air, const float* __restrict wx,
                      const float* __restrict wy, int nx, int y, long origin, long pitch,
                      const saltation::Params p, long* __restrict target,
                      units_t* __restrict parts) {
  // (Parameters by value: int64 stores could alias fields read through a
  // reference, which would block vectorisation.)
  for (int x = 0; x < nx; ++x) {
    const saltation::Landing L = saltation::landing(x, y, {wx[x], wy[x]}, p);
    units_t q[4];
    saltation::split_bilinear(air[x], L.fx, L.fy, q);
    target[x] = origin + static_cast<long>(L.y0) * pitch + L.x0;
    parts[4 * x] = q[0];
    parts[4 * x + 1] = q[1];
    parts[4 * x + 2] = q[2];
    parts[4 * x + 3] = q[3];
    air[x] = 0;
  }
}
// The adds of split_row's parts (which may collide: scalar).
inline void add_splits(const long* target, const units_t* parts, int nx, long pitch,
                       units_t* landed) {
  for (int x = 0; x < nx; ++x) {
    const std::size_t k = 4 * static_cast<std::size_t>(x);
    const long t = target[x];
    landed[t] += parts[k];
    landed[t + 1] += parts[k + 1];
    landed[t + pitch] += parts[k + 2];
    landed[t + pitch + 1] += parts[k + 3];
  }
}

}  // namespace erg::cpu
