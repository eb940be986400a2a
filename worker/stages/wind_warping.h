// Multi-scale wind warping ([P19] 4.2, [N24] 3.3 eqs. 2-3).
//
// The venturi wind v is bent along the relief at two scales: with h_i the
// height smoothed by a Gaussian of radius R_i (sigma = R_i / 2),
//   w_w = sum_i c_i [(1 - alpha_i) v + alpha_i k_i grad(h_i)^perp],
//   alpha_i = min(|k_g grad h_i|, 1),
// where grad^perp is the gradient turned by 90 degrees towards v
// (v . grad^perp >= 0); the result is rescaled to |v| ([N24] 3.3).
//
// The smoothing radii (50-200 m) are far wider than any halo, so it is done on
// a coarse grid: heights are block-summed exactly (integers) into coarse cells
// no wider than a quarter of the smallest sigma, convolved by FFT on that
// periodic coarse grid with the analytic Gaussian transfer function (physical
// wave numbers, right on non-square domains), differentiated spectrally, and
// the two gradient fields are bilinearly interpolated back to cell centres.
// The coarse grid depends only on the domain, never on the tiling, so every
// tile sees the same smoothed field (DESIGN.md section 4).
#pragma once

#include "core/hd.h"
#include "core/vec2.h"

namespace erg::wind_warping {

// One scale of eq. 3.
ERG_HD Vec2 warp_one(Vec2 v, Vec2 grad, float deviation, float gradient_scale) {
  const Vec2 g = gradient_scale * grad;
  const float alpha = min_of(length(g), 1.0f);
  Vec2 perp{-g.y, g.x};
  if (dot(v, perp) < 0.0f) perp = -1.0f * perp;
  return (1.0f - alpha) * v + (alpha * deviation) * perp;
}

struct Params {
  float weight[2];     // c_i
  float deviation[2];  // k_i
  float gradient_scale;
};

// Eq. 2 plus the length restoration of [N24] 3.3.
ERG_HD Vec2 warp(Vec2 v, Vec2 grad_large, Vec2 grad_small, const Params& p) {
  const Vec2 w = p.weight[0] * warp_one(v, grad_large, p.deviation[0], p.gradient_scale) +
                 p.weight[1] * warp_one(v, grad_small, p.deviation[1], p.gradient_scale);
  const float lw = length(w);
  if (!(lw > 0.0f)) return v;
  return (length(v) / lw) * w;
}

// Gaussian transfer function at physical wave numbers (cycles per metre):
// FT of exp(-r^2 / 2 sigma^2) normalised to 1 at k = 0.
ERG_HD double gaussian_transfer(double kx, double ky, double sigma_m) {
  const double pi2 = 9.869604401089358;  // pi^2
  return exp(-2.0 * pi2 * sigma_m * sigma_m * (kx * kx + ky * ky));
}

// Bilinear sample of a periodic coarse field at fine cell centre (x, y)
// (global cell coordinates). Coarse cell (I, J) covers fine cells
// [I*cx, (I+1)*cx) x [J*cy, (J+1)*cy), centre at ((I + 0.5) cx, (J + 0.5) cy).
ERG_HD float sample_coarse(const float* coarse, int cnx, int cny, int cx, int cy, int gx, int gy) {
  const float fx = (static_cast<float>(gx) + 0.5f) / static_cast<float>(cx) - 0.5f;
  const float fy = (static_cast<float>(gy) + 0.5f) / static_cast<float>(cy) - 0.5f;
  const float x0f = floorf(fx), y0f = floorf(fy);
  const float tx = fx - x0f, ty = fy - y0f;
  int x0 = static_cast<int>(x0f), y0 = static_cast<int>(y0f);
  x0 = (x0 % cnx + cnx) % cnx;
  y0 = (y0 % cny + cny) % cny;
  const int x1 = (x0 + 1) % cnx, y1 = (y0 + 1) % cny;
  const float a = coarse[y0 * cnx + x0], b = coarse[y0 * cnx + x1];
  const float c = coarse[y1 * cnx + x0], d = coarse[y1 * cnx + x1];
  return (1.0f - ty) * ((1.0f - tx) * a + tx * b) + ty * ((1.0f - tx) * c + tx * d);
}

}  // namespace erg::wind_warping
