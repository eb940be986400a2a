// SPDX-License-Identifier: Apache-2.0
// The CPU's fast path of the wind shadow (stages/wind_shadow.h): a segment
// of a row marched step-major. wind_shadow::shadow is the plain per-cell
// path the GPU runs; tests/sim/test_cpu_fast_paths.cpp proves the two give
// the same bits.
#pragma once

#include "core/hd.h"
#include "stages/wind_shadow.h"

namespace erg::cpu {

constexpr int kSegment = 64;

// Marches cells x0..x1-1 of row y step by step: step j for every cell, then
// step j + 1, so the inner loop vectorises (with gathers for the bilinear
// samples); stops once every cell is fully shadowed.
inline void march_segment(const float* base, int pitch, const float* wx, const float* wy, int x0,
                          int x1, int y, const wind_shadow::Params& p, float* __restrict out) {
  const int n = x1 - x0;
  float ux[kSegment], uy[kSegment], h0[kSegment], best[kSegment];
  bool calm[kSegment];
  for (int i = 0; i < n; ++i) {
    const wind_shadow::Upwind u = wind_shadow::upwind({wx[x0 + i], wy[x0 + i]});
    ux[i] = u.ux;
    uy[i] = u.uy;
    calm[i] = u.calm;
    h0[i] = base[static_cast<long>(y) * pitch + x0 + i];
    best[i] = -1e30f;
  }
  for (int j = 1; j <= p.steps; ++j) {
    for (int i = 0; i < n; ++i)
      best[i] = max_of(
          best[i], wind_shadow::angle(base, pitch, x0 + i, y, {ux[i], uy[i], false}, j, h0[i], p));
    float least = best[0];
    for (int i = 1; i < n; ++i) least = min_of(least, best[i]);
    if (least >= p.tan_max) break;  // every cell is at 1 already
  }
  for (int i = 0; i < n; ++i)
    out[x0 + i] = (calm[i] || p.steps <= 0) ? 0.0f : wind_shadow::from_angle(best[i], p);
}

}  // namespace erg::cpu
