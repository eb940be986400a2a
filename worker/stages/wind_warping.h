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
// of c x c fine cells, c the largest power of two with c l <= sigma_min / 4
// (model lengths only, never the domain size: coarse_factor); each tile
// gets a coarse halo of the cells within the kernels' reach (dist/exchange.h,
// coarse_window), convolves it with a truncated, normalised, sampled
// Gaussian of each scale (separable: along y, then along x, every sum in a
// fixed tap order, in double), takes central differences of the smoothed
// heights, and interpolates the two gradient fields bilinearly back to cell
// centres. Every coarse cell is a function of the same coarse values in the
// same order on any tiling, so the bits do not depend on it
// (docs/design.md, "Wind warping").
#pragma once

#include <cmath>
#include <cstddef>

#include "core/hd.h"
#include "core/vec2.h"

namespace erg {

// The coarse grid of the wind-warping smoothing.
struct CoarseGrid {
  int cx = 1, cy = 1;          // fine cells per coarse cell along x, y
  int nx = 0, ny = 0;          // coarse cells of the domain
  double cell_m = 1;           // fine cell edge l
  double sigma_m[2] = {0, 0};  // Gaussian sigma of the large and small scales
  // Kernel taps on each side, per scale and axis: ceil(4 sigma / (c l)).
  int radius_x[2] = {0, 0}, radius_y[2] = {0, 0};
  // Coarse halo of a tile: the widest kernel, one cell for the central
  // difference and one for the bilinear interpolation of the tile's edge.
  int halo_x = 2, halo_y = 2;
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

// The truncated Gaussian (host): taps w[0 .. 2 r] for offsets -r .. r of
// coarse cells `delta_m` wide, w_k = exp(-(k delta)^2 / 2 sigma^2) / sum.
// Truncation at 4 sigma leaves out erfc(4 / sqrt 2) = 6.3e-5 of the mass per
// axis; renormalised, the smoothed height differs from the untruncated one by
// at most 2 x 6.3e-5 x (the height range within 4 sigma) per pass
// (docs/design.md, "Wind warping"). Sums run in one order (convolve).
inline constexpr double kTruncationSigmas = 4.0;
inline int kernel_radius(double sigma_m, double delta_m) {
  return static_cast<int>(std::ceil(kTruncationSigmas * sigma_m / delta_m - 1e-9));
}
inline void gaussian_kernel(double sigma_m, double delta_m, int r, double* w) {
  double sum = 0;
  for (int k = -r; k <= r; ++k) {
    const double x = k * delta_m / sigma_m;
    w[k + r] = std::exp(-0.5 * x * x);
    sum += w[k + r];
  }
  for (int k = 0; k <= 2 * r; ++k) w[k] /= sum;
}
// One output of a 1-D pass: `in` points at the centre tap, `stride` apart.
// The kernel is symmetric (w[r - k] == w[r + k] exactly: the same x * x),
// so each pair of taps is added first and multiplied once, in one order:
// centre, then k = 1 .. r (a third fewer operations than tap by tap).
ERG_HD double convolve(const double* in, long stride, const double* w, int r) {
  double s = w[r] * in[0];
  for (int k = 1; k <= r; ++k) {
    const long o = static_cast<long>(k) * stride;
    s += w[r + k] * (in[-o] + in[o]);
  }
  return s;
}
// The gradient of the smoothed heights by central differences (second
// order; at >= 4 coarse cells per sigma its relative error is below
// (delta / sigma)^2 / 6 = 1%).
ERG_HD float central_difference(double minus, double plus, double delta_m) {
  return static_cast<float>((plus - minus) / (2.0 * delta_m));
}

// The smoothing of one tile, as arrays of its coarse window (host and
// device alike). With tcnx x tcny the tile's coarse cells and hx, hy the
// halo, the input window is (tcny + 2 hy) rows of (tcnx + 2 hx):
//   rows   = the smoothed-along-y window: rows -2 .. tcny + 1 of the tile,
//            every column of the window ((tcny + 4) x (tcnx + 2 hx));
//   smooth = rows smoothed along x: (tcny + 4) x (tcnx + 4), the tile's
//            coarse cells -2 .. tcn + 1;
//   gradient at coarse cells -1 .. tcn: (tcny + 2) x (tcnx + 2).
struct TileWindow {
  int tcnx, tcny, hx, hy;
  ERG_HD int wx() const { return tcnx + 2 * hx; }
  ERG_HD int wy() const { return tcny + 2 * hy; }
};
// rows[j][i] (j in 0 .. tcny + 3, i in 0 .. wx - 1): along y, at window row
// j + hy - 2.
ERG_HD double rows_at(const double* window, TileWindow t, const double* w, int r, int i, int j) {
  return convolve(window + static_cast<long>(j + t.hy - 2) * t.wx() + i, t.wx(), w, r);
}
// smooth[j][i] (j in 0 .. tcny + 3, i in 0 .. tcnx + 3): along x, at window
// column i + hx - 2.
ERG_HD double smooth_at(const double* rows, TileWindow t, const double* w, int r, int i, int j) {
  return convolve(rows + static_cast<long>(j) * t.wx() + i + t.hx - 2, 1, w, r);
}
// The gradient at gradient cell (i, j), i.e. the tile's coarse cell
// (i - 1, j - 1).
ERG_HD Vec2 gradient_at(const double* smooth, TileWindow t, double dx_m, double dy_m, int i,
                        int j) {
  const long sx = t.tcnx + 4;
  const double* c = smooth + static_cast<long>(j + 1) * sx + (i + 1);
  return {central_difference(c[-1], c[1], dx_m), central_difference(c[-sx], c[sx], dy_m)};
}

// Bilinear interpolation of a tile's coarse gradients at fine cell centres.
// Coarse cell I covers fine cells [I*c, (I+1)*c) along an axis, centred at
// (I + 0.5) c. Along one axis, global fine cell g falls between coarse
// centres i0 and i1 with weight t towards i1; the weight is computed from
// the global index (the same bits on any tiling), the indices are those of
// the tile's gradient arrays (its coarse cells -1 .. tcn, so index I - I0 + 1
// for the tile's first coarse cell I0). This depends only on the column (or
// row), so the CPU computes it once per tile and the GPU per cell.
struct Axis {
  int i0, i1;  // indices into the tile's gradient arrays
  float t;     // weight of i1
};
ERG_HD Axis coarse_axis(int g, int c, int first_coarse) {
  const float f = (static_cast<float>(g) + 0.5f) / static_cast<float>(c) - 0.5f;
  const float f0 = floorf(f);
  const int i0 = static_cast<int>(f0) - first_coarse + 1;
  return {i0, i0 + 1, f - f0};
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

// The coarse factor (host): the largest power of two c with c l <= max_m (a
// quarter of the smaller sigma), at least 1. It depends only on the model's
// lengths and the cell size, never on the domain, so a terrain gives the
// same wind on any torus it tiles; the domain's sides must be multiples of
// it (job validation says so, naming the allowed sizes).
inline int coarse_factor(double cell_m, double max_m) {
  int c = 1;
  while (2.0 * c * cell_m <= max_m && c < (1 << 20)) c *= 2;
  return c;
}
// The widest coarse cell the two smoothing scales allow: a quarter of the
// smaller sigma.
inline double max_coarse_m(double sigma_large_m, double sigma_small_m) {
  return 0.25 * (sigma_large_m < sigma_small_m ? sigma_large_m : sigma_small_m);
}
// A smoothing radius of the job (model.warp_*_radius_m) as a sigma: "we use
// r = 2 sigma" [N24 3.3].
inline double sigma_of_radius(double radius_m) {
  return 0.5 * radius_m;
}
// The coarse factor of a job's two warping radii.
inline int coarse_factor_of_radii(double cell_m, double large_radius_m, double small_radius_m) {
  return coarse_factor(
      cell_m, max_coarse_m(sigma_of_radius(large_radius_m), sigma_of_radius(small_radius_m)));
}

// The coarse grid of a domain (host): factors, kernel radii and halo.
inline CoarseGrid coarse_grid(int gnx, int gny, double cell_m, double sigma_large_m,
                              double sigma_small_m) {
  CoarseGrid c;
  c.sigma_m[0] = sigma_large_m;
  c.sigma_m[1] = sigma_small_m;
  c.cell_m = cell_m;
  c.cx = c.cy = coarse_factor(cell_m, max_coarse_m(sigma_large_m, sigma_small_m));
  c.nx = gnx / c.cx;
  c.ny = gny / c.cy;
  c.halo_x = c.halo_y = 0;
  for (int s = 0; s < 2; ++s) {
    c.radius_x[s] = kernel_radius(c.sigma_m[s], c.cx * cell_m);
    c.radius_y[s] = kernel_radius(c.sigma_m[s], c.cy * cell_m);
    c.halo_x = c.radius_x[s] + 2 > c.halo_x ? c.radius_x[s] + 2 : c.halo_x;
    c.halo_y = c.radius_y[s] + 2 > c.halo_y ? c.radius_y[s] + 2 : c.halo_y;
  }
  return c;
}

}  // namespace erg::wind_warping
