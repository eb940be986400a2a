// SPDX-License-Identifier: Apache-2.0
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
// tile sees the same smoothed field (docs/design.md, "Tiling").
#pragma once

#include <cstddef>

#include "core/hd.h"
#include "core/vec2.h"

namespace erg {

// The coarse grid of the wind-warping smoothing.
struct CoarseGrid {
  int cx = 1, cy = 1;          // fine cells per coarse cell along x, y
  int nx = 0, ny = 0;          // coarse cells
  double lx_m = 0, ly_m = 0;   // domain extent
  double sigma_m[2] = {0, 0};  // Gaussian sigma of the large and small scales
};

}  // namespace erg

namespace erg::wind_warping {

// One scale of eq. 3.
ERG_HD Vec2 warp_one(Vec2 v, Vec2 grad, float deviation, float gradient_scale) {
  const Vec2 g = gradient_scale * grad;
  const float alpha = min_of(length(g), 1.0f);
  const Vec2 perp{-g.y, g.x};
  const float side = dot(v, perp) < 0.0f ? -1.0f : 1.0f;  // towards v
  return (1.0f - alpha) * v + (side * (alpha * deviation)) * perp;
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
  const bool ok = lw > 0.0f;  // (selects, no branch: the loop vectorises)
  const float scale = length(v) / (ok ? lw : 1.0f);
  return ok ? scale * w : v;
}

// Gaussian transfer function at physical wave numbers (cycles per metre):
// FT of exp(-r^2 / 2 sigma^2) normalised to 1 at k = 0.
ERG_HD double gaussian_transfer(double kx, double ky, double sigma_m) {
  const double pi2 = 9.869604401089358;  // pi^2
  return exp(-2.0 * pi2 * sigma_m * sigma_m * (kx * kx + ky * ky));
}

// The spectral Gaussian gradients of the coarse heights, on the half
// spectrum of a real 2-D transform ([ny][nx / 2 + 1], FFTW's and cuFFT's
// layout): mode (i, j) at physical wave numbers, j past ny / 2 negative.
struct WaveNumber {
  double kx, ky;
};
ERG_HD WaveNumber wave_number(const CoarseGrid& c, int i, int j) {
  const int mj = j <= c.ny / 2 ? j : j - c.ny;
  return {i / c.lx_m, mj / c.ly_m};
}
// The Gaussian of scale s at every mode, times the 1 / n of the unnormalised
// inverse transform: computed once per run.
inline void gaussian_table(const CoarseGrid& c, int s, double* out) {
  const int hx = c.nx / 2 + 1;
  const double norm = 1.0 / static_cast<double>(static_cast<std::size_t>(c.nx) * c.ny);
  for (int j = 0; j < c.ny; ++j)
    for (int i = 0; i < hx; ++i) {
      const WaveNumber k = wave_number(c, i, j);
      out[static_cast<std::size_t>(j) * hx + i] =
          gaussian_transfer(k.kx, k.ky, c.sigma_m[s]) * norm;
    }
}
// Mode (i, j) of the spectrum (re, im) times its Gaussian g times the
// derivative along `axis` (0: x): d/dx <-> 2 pi i k_x. The Nyquist mode of
// the differentiated axis has no sign and is dropped.
struct Mode {
  double re, im;
};
ERG_HD Mode gradient_mode(const CoarseGrid& c, int i, int j, int axis, double re, double im,
                          double g) {
  const double two_pi = 6.283185307179586;
  const WaveNumber k = wave_number(c, i, j);
  const double factor = two_pi * (axis == 0 ? k.kx : k.ky);
  const bool nyquist =
      axis == 0 ? (c.nx % 2 == 0) && i == c.nx / 2 : (c.ny % 2 == 0) && j == c.ny / 2;
  const double a = re * g, b = im * g;
  // (a + i b) * (i factor) = -b factor + i a factor
  return {nyquist ? 0.0 : -b * factor, nyquist ? 0.0 : a * factor};
}

// Bilinear interpolation of a periodic coarse field at fine cell centres.
// Coarse cell I covers fine cells [I*c, (I+1)*c) along an axis, centred at
// (I + 0.5) c. Along one axis, fine cell g falls between coarse centres i0
// and i1 with weight t towards i1; this depends only on the column (or row),
// so the CPU computes it once per tile and the GPU per cell, with this code.
struct Axis {
  int i0, i1;  // coarse indices, wrapped
  float t;     // weight of i1
};
ERG_HD Axis coarse_axis(int g, int c, int n) {
  const float f = (static_cast<float>(g) + 0.5f) / static_cast<float>(c) - 0.5f;
  const float f0 = floorf(f);
  int i0 = static_cast<int>(f0);
  i0 = (i0 % n + n) % n;
  return {i0, (i0 + 1) % n, f - f0};
}
// Interpolate along y first (between two coarse rows, at column i), then
// along x. The CPU does the first part once per row of cells.
ERG_HD float lerp_rows(const float* coarse, int nx, Axis ay, int i) {
  return (1.0f - ay.t) * coarse[ay.i0 * nx + i] + ay.t * coarse[ay.i1 * nx + i];
}
ERG_HD float lerp_columns(float at_i0, float at_i1, Axis ax) {
  return (1.0f - ax.t) * at_i0 + ax.t * at_i1;
}
ERG_HD float sample_at(const float* coarse, int nx, Axis ax, Axis ay) {
  return lerp_columns(lerp_rows(coarse, nx, ay, ax.i0), lerp_rows(coarse, nx, ay, ax.i1), ax);
}
// The same, at global fine cell (gx, gy) of a coarse grid cnx x cny with
// cx x cy fine cells per coarse cell.
ERG_HD float sample_coarse(const float* coarse, int cnx, int cny, int cx, int cy, int gx, int gy) {
  return sample_at(coarse, cnx, coarse_axis(gx, cx, cnx), coarse_axis(gy, cy, cny));
}

// The coarse grid (host). Coarse factor along one axis: the largest divisor
// c of n whose coarse cells are at most `max_m` wide (a quarter of the smaller
// sigma) with at most kMaxCoarseCells coarse cells; on huge domains, the
// smallest divisor that keeps the grid that small, which widens the smallest
// smoothing a little (README, "Scaling"). 0 when no divisor works (n prime
// and larger than kMaxCoarseCells).
inline constexpr int kMaxCoarseCells = 2048;
inline int coarse_factor(int n, double cell_m, double max_m) {
  int best = 0;
  for (int c = 1; c <= n; ++c)
    if (n % c == 0 && c * cell_m <= max_m && n / c <= kMaxCoarseCells) best = c;
  if (best > 0) return best;
  for (int c = 1; c <= n; ++c)
    if (n % c == 0 && n / c <= kMaxCoarseCells) return n / c >= 2 ? c : 0;
  return 0;
}

}  // namespace erg::wind_warping
