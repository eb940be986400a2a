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

// Bilinear sample of a padded field. `base` points at local cell (0, 0);
// (px, py) are local cell coordinates within the halo.
ERG_HD float bilinear(const float* base, int pitch, float px, float py) {
  const float x0f = floorf(px), y0f = floorf(py);
  const float tx = px - x0f, ty = py - y0f;
  const float* r0 = base + static_cast<long>(y0f) * pitch + static_cast<long>(x0f);
  const float* r1 = r0 + pitch;
  return (1.0f - ty) * ((1.0f - tx) * r0[0] + tx * r0[1]) + ty * ((1.0f - tx) * r1[0] + tx * r1[1]);
}

struct Params {
  int steps;           // N_s
  float cell_m;        // l
  float tan_min, tan_max;
};

// True when the shadow is certainly 0: `hmax` bounds every height the march
// can sample (bilinear samples are convex combinations), so no angle reaches
// tan_min. The small margin covers the rounding of a float bilinear sample
// and of the division; a cell it selects is exactly one shadow() returns 0
// for, so skipping the march changes nothing.
ERG_HD bool certainly_unshadowed(float hmax, float h0, const Params& p) {
  const float margin = 1e-6f * (fabsf(hmax) + fabsf(h0)) + 1e-6f;
  return (hmax - h0) + margin < p.tan_min * p.cell_m;
}

ERG_HD float shadow(const float* h_base, int pitch, int x, int y, Vec2 w, const Params& p) {
  const float speed = length(w);
  if (!(speed > 0.0f) || p.steps <= 0) return 0.0f;
  const float ux = -w.x / speed, uy = -w.y / speed;  // upwind unit step
  const float h0 = h_base[static_cast<long>(y) * pitch + x];
  float best = -1e30f;
  for (int j = 1; j <= p.steps; ++j) {
    const float fj = static_cast<float>(j);
    const float hq = bilinear(h_base, pitch, static_cast<float>(x) + fj * ux,
                              static_cast<float>(y) + fj * uy);
    best = max_of(best, (hq - h0) / (fj * p.cell_m));
    if (best >= p.tan_max) return 1.0f;
  }
  return clamp_to((best - p.tan_min) / (p.tan_max - p.tan_min), 0.0f, 1.0f);
}

}  // namespace erg::wind_shadow
