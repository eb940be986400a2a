// SPDX-License-Identifier: Apache-2.0
// Wind shadow ([P19] 4.3, [N24] 3.4 eq. 4, linear mode).
//
// From a cell, march upwind N_s = ceil(R_s / l) steps of one cell length,
// sampling the height between cells (model.shadow_sampling: [N24]'s
// bilinear sample by default, or cubic convolution), and keep
// the maximum angle
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

// Cubic convolution sample (Keys 1981, "Cubic convolution interpolation
// for digital image processing", IEEE Trans. ASSP 29, 1153-1160, with
// a = -1/2) on the 4 x 4 cells around the point, split into whole cells and
// a fraction as bilinear() is. Why not bilinear: a bilinear sample a
// fraction f past a cell is a local mean with variance f (1 - f) cell^2 per
// axis, none for a march along a grid axis (every sample on a cell) and up
// to 1/4 cell^2 across it, so a sharp brink casts a longer shadow when the
// wind is along an axis, and dunes lost sand at rates that depended on the
// wind's angle to the grid (docs/dune-forms.md, "Isotropy"). Keys' kernel
// is exact on cells and reproduces quadratic surfaces, so its smoothing is
// small at every fraction. Its weights for the cells -1, 0, 1, 2 at
// fraction t, written out in one order for host and device (no fused
// multiply-adds: the build forbids them):
struct Cubic {
  float w[4];
};
ERG_HD Cubic cubic_weights(float t) {
  return {{((-0.5f * t + 1.0f) * t - 0.5f) * t, (1.5f * t - 2.5f) * t * t + 1.0f,
           ((-1.5f * t + 2.0f) * t + 0.5f) * t, (0.5f * t - 0.5f) * t * t}};
}
ERG_HD float cubic(const float* base, int pitch, int x, int y, float dx, float dy) {
  const float fx = floorf(dx), fy = floorf(dy);
  const Cubic wx = cubic_weights(dx - fx), wy = cubic_weights(dy - fy);
  const long i0 =
      static_cast<long>(y + static_cast<int>(fy) - 1) * pitch + (x + static_cast<int>(fx) - 1);
  float acc = 0.0f;
  for (int j = 0; j < 4; ++j) {
    const long i = i0 + j * static_cast<long>(pitch);
    acc += wy.w[j] * (((wx.w[0] * base[i] + wx.w[1] * base[i + 1]) + wx.w[2] * base[i + 2]) +
                      wx.w[3] * base[i + 3]);
  }
  return acc;
}
// A cubic sample can overshoot the heights it reads (its outer weights are
// negative): at most by this times (max - min) of the 4 x 4 cells (the
// negative weights sum to at most 2 x 1.125 x 0.125 = 0.28125, at t = 1/2
// on both axes; rounded up for float rounding).
inline constexpr float kCubicOvershoot = 0.2813f;

inline constexpr int kMaxShadowSteps = 128;  // the validator's limit (128 cells)

struct Params {
  int steps;     // N_s
  float cell_m;  // l
  float tan_min, tan_max;
  bool cubic;  // model.shadow_sampling: cubic(), or bilinear() (the default)
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

// The cells the march's samples read beyond its N_s steps: bilinear reads
// one more cell, cubic two.
ERG_HD int footprint(const Params& p) {
  return p.cubic ? 2 : 1;
}

// True when the shadow is certainly 0: `hmax` bounds every height the march
// can sample (bilinear samples are convex combinations of the heights they
// read; a cubic one needs sample_bound()), so no angle reaches tan_min. The small margin covers the
// rounding of a float bilinear sample and of the division; a cell it selects is exactly one
// shadow() returns 0 for, so skipping the march changes nothing.
ERG_HD bool certainly_unshadowed(float hmax, float h0, const Params& p) {
  const float margin = 1e-6f * (fabsf(hmax) + fabsf(h0)) + 1e-6f;
  return (hmax - h0) + margin < p.tan_min * p.cell_m;
}

// A bound on every sample the march can take from heights within
// [hmin, hmax].
ERG_HD float sample_bound(float hmax, float hmin, const Params& p) {
  return p.cubic ? hmax + kCubicOvershoot * (hmax - hmin) : hmax;
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
  const float hq = p.cubic ? cubic(h_base, pitch, x, y, fj * u.ux, fj * u.uy)
                           : bilinear(h_base, pitch, x, y, fj * u.ux, fj * u.uy);
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
