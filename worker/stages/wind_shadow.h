// SPDX-License-Identifier: Apache-2.0
// Wind shadow ([P19] 4.3, [N24] 3.4 eq. 4, linear mode).
//
// From a cell, march upwind N_s = ceil(R_s / l) steps of one cell length,
// sampling the height bilinearly, and keep the maximum angle
//   tan(alpha) = max_j (h(p - j u) - h(p)) / (j l),  u = w / |w|;
// the shadow is 0 below tan(10 deg), 1 above tan(15 deg), linear between.
// The march stops as soon as the shadow is certainly 1 (the result is the
// same, only cheaper).
#pragma once

#include "core/hd.h"
#include "core/vec2.h"

namespace erg::wind_shadow {

// Bilinear sample of a padded field at local cell (x, y) shifted by
// (dx, dy) cells. The shift is split into whole cells and a fraction on its
// own, never added to the cell's coordinates in floating point: the weights
// then depend only on the shift, not on where the tile starts, so every
// tiling computes the same sample (tiling invariance, docs/design.md
// "Exactness").
// `base` points at local cell (0, 0).
ERG_HD float bilinear(const float* base, int pitch, int x, int y, float dx, float dy) {
  const float fx = floorf(dx), fy = floorf(dy);
  const float tx = dx - fx, ty = dy - fy;
  // An index, not a pointer: compilers vectorise indexed loads as gathers.
  const long i = static_cast<long>(y + static_cast<int>(fy)) * pitch + (x + static_cast<int>(fx));
  return (1.0f - ty) * ((1.0f - tx) * base[i] + tx * base[i + 1]) +
         ty * ((1.0f - tx) * base[i + pitch] + tx * base[i + pitch + 1]);
}

inline constexpr int kMaxShadowSteps = 128;  // the validator's limit (128 cells)

struct Params {
  int steps;     // N_s
  float cell_m;  // l
  float tan_min, tan_max;
  // 1 / (j l) for j = 0..steps: the march multiplies instead of dividing
  // (10 divisions per cell were most of this stage's time on the CPU).
  float inv_distance[kMaxShadowSteps + 1];
};

// Fills inv_distance from steps and cell_m (host).
inline void finish(Params& p) {
  p.inv_distance[0] = 0.0f;
  for (int j = 1; j <= kMaxShadowSteps; ++j)
    p.inv_distance[j] = 1.0f / (static_cast<float>(j) * p.cell_m);
}

// True when the shadow is certainly 0: `hmax` bounds every height the march
// can sample (bilinear samples are convex combinations), so no angle reaches
// tan_min. The small margin covers the rounding of a float bilinear sample
// and of the division; a cell it selects is exactly one shadow() returns 0
// for, so skipping the march changes nothing.
ERG_HD bool certainly_unshadowed(float hmax, float h0, const Params& p) {
  const float margin = 1e-6f * (fabsf(hmax) + fabsf(h0)) + 1e-6f;
  return (hmax - h0) + margin < p.tan_min * p.cell_m;
}

// The march, in pieces (the CPU runs them step-major over a row of cells so
// that it vectorises; the GPU calls shadow() per cell). All give the same
// values: a maximum does not depend on the order it is taken in.

// Upwind unit step of a wind; calm when there is no wind.
struct Upwind {
  float ux, uy;
  bool calm;
};
ERG_HD Upwind upwind(Vec2 w) {
  const float speed = length(w);
  const bool calm = !(speed > 0.0f);
  const float inv = 1.0f / (calm ? 1.0f : speed);
  return {-w.x * inv, -w.y * inv, calm};
}

// tan of the angle to the j-th sample upwind of local cell (x, y).
ERG_HD float angle(const float* h_base, int pitch, int x, int y, Upwind u, int j, float h0,
                   const Params& p) {
  const float fj = static_cast<float>(j);
  const float hq = bilinear(h_base, pitch, x, y, fj * u.ux, fj * u.uy);
  return (hq - h0) * p.inv_distance[j];
}

// The shadow for the largest angle found (linear from tan_min to tan_max).
ERG_HD float from_angle(float best, const Params& p) {
  return clamp_to((best - p.tan_min) / (p.tan_max - p.tan_min), 0.0f, 1.0f);
}

// The shadow of one cell. `p.steps` must not exceed kMaxShadowSteps.
ERG_HD float shadow(const float* h_base, int pitch, int x, int y, Vec2 w, const Params& p) {
  const Upwind u = upwind(w);
  if (u.calm || p.steps <= 0) return 0.0f;
  const float h0 = h_base[static_cast<long>(y) * pitch + x];
  float best = -1e30f;
  for (int j = 1; j <= p.steps; ++j) {
    best = max_of(best, angle(h_base, pitch, x, y, u, j, h0, p));
    if (best >= p.tan_max) return 1.0f;  // from_angle(best) would be 1 too
  }
  return from_angle(best, p);
}

}  // namespace erg::wind_shadow
