// SPDX-License-Identifier: Apache-2.0
// Surface wind on the CPU: venturi and multi-scale warping
// (stages/venturi.h, stages/wind_warping.h), then the local wind primitives
// (stages/wind_primitives.h).
#include <algorithm>
#include <cmath>
#include <vector>

#include "backend/cpu/cpu_backend.h"
#include "stages/obstacles.h"
#include "stages/shear_stress.h"
#include "stages/venturi.h"
#include "stages/wind_primitives.h"
#include "stages/wind_warping.h"

namespace erg::cpu {

CoarseSmoother::CoarseSmoother(const CoarseGrid& c, int tcnx, int tcny)
    : c_(c), t_{tcnx, tcny, c.halo_x, c.halo_y} {
  for (int s = 0; s < 2; ++s) {
    kx_[s].resize(2 * static_cast<size_t>(c.radius_x[s]) + 1);
    ky_[s].resize(2 * static_cast<size_t>(c.radius_y[s]) + 1);
    wind_warping::gaussian_kernel(c.sigma_m[s], c.cx * c.cell_m, c.radius_x[s], kx_[s].data());
    wind_warping::gaussian_kernel(c.sigma_m[s], c.cy * c.cell_m, c.radius_y[s], ky_[s].data());
  }
}

// The passes of wind_warping::rows_at, smooth_at and gradient_at, with the
// taps in the outer loop and the cells in the inner one so that it
// vectorises: every output still sums the centre tap, then the pairs
// w[r + k] (x[-k] + x[k]) for k = 1 .. r, in that order (no contraction:
// -ffp-contract=off), so the bits are those of wind_warping::convolve.
//
// Fused over blocks of gradient rows: a block of kRowBlock gradient rows
// needs kRowBlock + 2 smoothed rows (the central difference along y), which
// need as many rows of the pass along y. Each thread keeps those rows in
// its own two buffers, so no pass is ever stored for the whole tile (the
// two passes of both scales were 32 bytes per coarse cell, about 2 bytes
// per fine cell at the default radii: docs/design.md, "Memory"); the two
// smoothed rows a block shares with the next are computed twice, the same
// bits both times.
void CoarseSmoother::gradients(const std::vector<double>& window, std::vector<float> grad_x[2],
                               std::vector<float> grad_y[2], int threads) {
  const wind_warping::TileWindow t = t_;
  const int wx = t.wx(), sx = t.tcnx + 4;
  const int gnx = t.tcnx + 2, gny = t.tcny + 2;
  const double dx = c_.cx * c_.cell_m, dy = c_.cy * c_.cell_m;
  for (int s = 0; s < 2; ++s) {
    grad_x[s].resize(static_cast<size_t>(gnx) * gny);
    grad_y[s].resize(static_cast<size_t>(gnx) * gny);
  }
  // Strips of columns in the pass along y, so that the 2 r + 1 input rows a
  // strip reads stay in cache from one output row to the next.
  constexpr int kRowBlock = 32, kStrip = 64;
  const int blocks = (gny + kRowBlock - 1) / kRowBlock;
#pragma omp parallel num_threads(threads)
  {
    // Rows j0 .. j0 + kRowBlock + 1 of the pass along y (window columns as
    // in the window) and of the smoothed heights (smooth[j][i] of
    // wind_warping::smooth_at), for the block being computed.
    std::vector<double> along_y(static_cast<size_t>(kRowBlock + 2) * wx);
    std::vector<double> smooth(static_cast<size_t>(kRowBlock + 2) * sx);
#pragma omp for schedule(static)
    for (int sb = 0; sb < 2 * blocks; ++sb) {
      const int s = sb / blocks, j0 = (sb % blocks) * kRowBlock;
      const int j1 = j0 + kRowBlock < gny ? j0 + kRowBlock : gny;
      const int n_rows = j1 - j0 + 2;  // smoothed rows j0 .. j1 + 1
      const int rx = c_.radius_x[s], ry = c_.radius_y[s];
      const double* wy = ky_[s].data();
      // Along y, only at the columns the pass along x reads.
      const int i0 = t.hx - 2 - rx, i1 = t.hx + t.tcnx + 2 + rx;
      for (int ib = i0; ib < i1; ib += kStrip) {
        const int n = ib + kStrip < i1 ? kStrip : i1 - ib;
        for (int r = 0; r < n_rows; ++r) {
          double acc[kStrip];
          const double* centre = window.data() + static_cast<size_t>(j0 + r + t.hy - 2) * wx + ib;
          for (int i = 0; i < n; ++i) acc[i] = wy[ry] * centre[i];
          for (int k = 1; k <= ry; ++k) {
            const double w = wy[ry + k];
            const double* __restrict lo = centre - static_cast<size_t>(k) * wx;
            const double* __restrict hi = centre + static_cast<size_t>(k) * wx;
            for (int i = 0; i < n; ++i) acc[i] += w * (lo[i] + hi[i]);
          }
          double* __restrict out = along_y.data() + static_cast<size_t>(r) * wx + ib;
          for (int i = 0; i < n; ++i) out[i] = acc[i];
        }
      }
      const double* wxk = kx_[s].data();
      for (int r = 0; r < n_rows; ++r) {
        double* __restrict out = smooth.data() + static_cast<size_t>(r) * sx;
        const double* centre = along_y.data() + static_cast<size_t>(r) * wx + (t.hx - 2);
        for (int i = 0; i < sx; ++i) out[i] = wxk[rx] * centre[i];
        for (int k = 1; k <= rx; ++k) {
          const double w = wxk[rx + k];
          const double* __restrict lo = centre - k;
          const double* __restrict hi = centre + k;
          for (int i = 0; i < sx; ++i) out[i] += w * (lo[i] + hi[i]);
        }
      }
      // smooth holds rows j0 .. j1 + 1: gradient row j reads j .. j + 2.
      for (int j = j0; j < j1; ++j)
        for (int i = 0; i < gnx; ++i) {
          const Vec2 g = wind_warping::gradient_at(smooth.data(), t, dx, dy, i, j - j0);
          grad_x[s][static_cast<size_t>(j) * gnx + i] = g.x;
          grad_y[s][static_cast<size_t>(j) * gnx + i] = g.y;
        }
    }
  }
}

namespace {
// Venturi and warping along one row (outside the OpenMP region so that GCC
// vectorises it). rows[f] holds the four gradient fields already
// interpolated to this row's y (wind_warping::lerp_rows).
void warp_row(const float* h, float* __restrict wx, float* __restrict wy, int nx, Vec2 a, float k,
              const wind_warping::Params wp, const int* __restrict ax_i0,
              const int* __restrict ax_i1, const float* __restrict ax_t,
              const float* __restrict gx0, const float* __restrict gy0, const float* __restrict gx1,
              const float* __restrict gy1) {
  for (int x = 0; x < nx; ++x) {
    const wind_warping::Axis ax{ax_i0[x], ax_i1[x], ax_t[x]};
    const Vec2 v = venturi::wind(a, h[x], k);
    const Vec2 gl{wind_warping::lerp_columns(gx0[ax.i0], gx0[ax.i1], ax),
                  wind_warping::lerp_columns(gy0[ax.i0], gy0[ax.i1], ax)};
    const Vec2 gs{wind_warping::lerp_columns(gx1[ax.i0], gx1[ax.i1], ax),
                  wind_warping::lerp_columns(gy1[ax.i0], gy1[ax.i1], ax)};
    const Vec2 w = wind_warping::warp(v, gl, gs, wp);
    wx[x] = w.x;
    wy[x] = w.y;
  }
}
}  // namespace

void CpuBackend::heights() {
  const CoarseGrid& c = m_.coarse;
  // One pass over the layers: heights in metres, and the exact block sums of
  // the coarse cells this tile owns (tiles are aligned to coarse cells):
  // int64 per row of a block, 128 bits per block, so the mean of a coarse
  // cell is the same whichever tile computes it.
  const int cnx = g_.nx / c.cx, cny = g_.ny / c.cy;
  coarse_mine_.assign(static_cast<size_t>(cnx) * cny, 0.0);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int J = 0; J < cny; ++J) {
    std::vector<total_t> sums(static_cast<size_t>(cnx), 0);
    for (int y = J * c.cy; y < (J + 1) * c.cy; ++y) {
      const units_t* b = f_.bedrock.row(y);
      const units_t* s = f_.sand.row(y);
      const float* o = f_.obstacles.row(y);
      float* h = f_.height_m.row(y);
      // The wind sees obstacles as terrain [BR04 4.3] (stages/obstacles.h).
      for (int x = 0; x < g_.nx; ++x) h[x] = units_to_m(b[x] + s[x]) + o[x];
      for (int I = 0; I < cnx; ++I) {
        units_t row = 0;
        for (int x = I * c.cx; x < (I + 1) * c.cx; ++x)
          row += b[x] + s[x] + obstacles::height_units(o[x]);
        sums[static_cast<size_t>(I)] += row;
      }
    }
    for (int I = 0; I < cnx; ++I)
      coarse_mine_[static_cast<size_t>(J) * cnx + I] =
          static_cast<double>(sums[static_cast<size_t>(I)]) * kUnitM /
          (static_cast<double>(c.cx) * c.cy);
  }
}

// tau1 / tau0 and tau_y / tau0 of the shear stress over relief at the
// tile's coarse cells -1 .. tcn (stages/shear_stress.h), from the coarse
// window: e . grad h and e_perp . grad h over the window's inner cells, then
// the truncated kernel and the corrections, with the taps in the outer loop
// and a row of outputs in the inner one (it vectorises); every output still
// sums each set of taps in its order from 0, then adds B D h and the
// correction and multiplies by A: the bits of shear_stress::perturbation_at
// and shear_stress::lateral_at (the GPU's), whatever the threads.
bool CpuBackend::shear_field(Vec2 a) {
  const shear_stress::Params p = m_.shear;
  if (!p.on || !shear_kernel_.aim(a, p)) return false;
  const wind_warping::TileWindow t = smoother_.tile();
  const int wx = t.wx(), wy = t.wy(), gnx = t.tcnx + 2, gny = t.tcny + 2;
  const double delta = m_.coarse.cx * m_.coarse.cell_m;
  const double ex = shear_kernel_.ex, ey = shear_kernel_.ey;
  shear_slope_.assign(static_cast<size_t>(wx) * wy, 0.0);
  shear_slope_perp_.assign(static_cast<size_t>(wx) * wy, 0.0);
  shear_tau_.resize(static_cast<size_t>(gnx) * gny);
  shear_tau_y_.resize(static_cast<size_t>(gnx) * gny);
  const shear_stress::TapsView k = shear_kernel_.kernel_taps();
  const shear_stress::TapsView c = shear_kernel_.correction_taps();
  const shear_stress::TapsView cp = shear_kernel_.lateral_taps();
#pragma omp parallel num_threads(threads_)
  {
#pragma omp for schedule(static)
    for (int j = 1; j < wy - 1; ++j)
      for (int i = 1; i < wx - 1; ++i) {
        const size_t at = static_cast<size_t>(j) * wx + i;
        shear_slope_[at] = shear_stress::slope_at(window_.data(), wx, ex, ey, delta, i, j);
        shear_slope_perp_[at] = shear_stress::slope_at(window_.data(), wx, -ey, ex, delta, i, j);
      }
    std::vector<double> acc(static_cast<size_t>(gnx)), cor(static_cast<size_t>(gnx));
    // One component: sum_n k[n] (D(p - o_n) - D(p + o_n)) into acc, sum_n
    // c[n] (h(p - o_n) - h(p)) into cor, over a row of outputs.
    auto sums = [&](const double* centre, const double* h, shear_stress::TapsView cc) {
      std::fill(acc.begin(), acc.end(), 0.0);
      std::fill(cor.begin(), cor.end(), 0.0);
      double* __restrict s = acc.data();
      for (int n = 0; n < k.n; ++n) {
        const long o = static_cast<long>(k.dv[n]) * wx + k.du[n];
        const double w = k.w[n];
        const double* __restrict lo = centre - o;
        const double* __restrict hi = centre + o;
        for (int i = 0; i < gnx; ++i) s[i] += w * (lo[i] - hi[i]);
      }
      double* __restrict q = cor.data();
      for (int n = 0; n < cc.n; ++n) {
        const long o = static_cast<long>(cc.dv[n]) * wx + cc.du[n];
        const double w = cc.w[n];
        const double* __restrict lo = h - o;
        for (int i = 0; i < gnx; ++i) q[i] += w * (lo[i] - h[i]);
      }
    };
#pragma omp for schedule(static)
    for (int j = 0; j < gny; ++j) {
      // Output (i, j) is window cell (hx - 1 + i, hy - 1 + j).
      const size_t at = static_cast<size_t>(t.hy - 1 + j) * wx + t.hx - 1;
      const double* h = window_.data() + at;
      const double a = p.a, b = p.b;
      const double* centre = shear_slope_.data() + at;
      sums(centre, h, c);
      float* __restrict out = shear_tau_.data() + static_cast<size_t>(j) * gnx;
      for (int i = 0; i < gnx; ++i)
        out[i] = static_cast<float>(a * ((acc[i] + b * centre[i]) + cor[i]));
      sums(shear_slope_perp_.data() + at, h, cp);
      float* __restrict out_y = shear_tau_y_.data() + static_cast<size_t>(j) * gnx;
      for (int i = 0; i < gnx; ++i) out_y[i] = static_cast<float>(a * (acc[i] + cor[i]));
    }
  }
  return true;
}

// Reads no ghosts: the heights' exchange may run meanwhile (Simulation::step).
void CpuBackend::wind(Vec2 a) {
  const wind_warping::TileWindow t = smoother_.tile();
  ex_.coarse_window(coarse_mine_, t.tcnx, t.tcny, t.hx, t.hy, window_);
  smoother_.gradients(window_, grad_x_, grad_y_, threads_);
  shear_on_ = shear_field(a);
  last_a_ = a;
  last_batches_.clear();
  wind_ran_ = true;
  warp_rows(a);
  wind_valid_ = true;
  shadow_valid_ = false;
  shadow_of_wind_ = false;
}

// Venturi and warping at every owned cell from the heights and this step's
// coarse gradients (no exchange): what wind() ends with, and what
// restore_outputs runs again for a snapshot after the wind's storage was
// reused within the step.
void CpuBackend::warp_rows(Vec2 a) {
  const CoarseGrid& c = m_.coarse;
  const wind_warping::TileWindow t = smoother_.tile();
  const float k = m_.venturi_k;
  const wind_warping::Params wp = m_.warp;
  const int gnx = t.tcnx + 2;  // the gradient arrays' width
  // Interpolation stencils depend only on the column or the row.
  if (axis_y_.empty()) {
    for (int x = 0; x < g_.nx; ++x) {
      const wind_warping::Axis ax = wind_warping::coarse_axis(g_.x0 + x, c.cx, g_.x0 / c.cx);
      axis_x_i0_.push_back(ax.i0);  // structure of arrays: gathers vectorise
      axis_x_i1_.push_back(ax.i1);
      axis_x_t_.push_back(ax.t);
    }
    for (int y = 0; y < g_.ny; ++y)
      axis_y_.push_back(wind_warping::coarse_axis(g_.y0 + y, c.cy, g_.y0 / c.cy));
  }
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y) {
    const wind_warping::Axis ay = axis_y_[static_cast<size_t>(y)];
    std::vector<float> rows(6 * static_cast<size_t>(gnx));
    const std::vector<float>* fields[4] = {&grad_x_[0], &grad_y_[0], &grad_x_[1], &grad_y_[1]};
    for (int f = 0; f < 4; ++f)
      for (int i = 0; i < gnx; ++i)
        rows[static_cast<size_t>(f) * gnx + i] =
            wind_warping::lerp_rows(fields[f]->data(), gnx, ay, i);
    warp_row(f_.height_m.row(y), f_.wind_x.row(y), f_.wind_y.row(y), g_.nx, a, k, wp,
             axis_x_i0_.data(), axis_x_i1_.data(), axis_x_t_.data(), rows.data(), rows.data() + gnx,
             rows.data() + 2 * gnx, rows.data() + 3 * gnx);
    if (!shear_on_) continue;
    // The surface wind carries u*: turned to the stress's direction and
    // scaled by the square root of its magnitude (shear_stress::surface_wind),
    // both components interpolated as the gradients are (the bits of
    // wind_warping::sample_at).
    float* tau = rows.data() + 4 * static_cast<size_t>(gnx);
    float* tau_y = rows.data() + 5 * static_cast<size_t>(gnx);
    for (int i = 0; i < gnx; ++i) {
      tau[i] = wind_warping::lerp_rows(shear_tau_.data(), gnx, ay, i);
      tau_y[i] = wind_warping::lerp_rows(shear_tau_y_.data(), gnx, ay, i);
    }
    float* __restrict wx = f_.wind_x.row(y);
    float* __restrict wy = f_.wind_y.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      const wind_warping::Axis ax{axis_x_i0_[x], axis_x_i1_[x], axis_x_t_[x]};
      const Vec2 w = shear_stress::surface_wind(
          wind_warping::lerp_columns(tau[ax.i0], tau[ax.i1], ax),
          wind_warping::lerp_columns(tau_y[ax.i0], tau_y[ax.i1], ax), {wx[x], wy[x]});
      wx[x] = w.x;
      wy[x] = w.y;
    }
  }
}

// Every owned cell from its global index only: no ghosts are read, and the
// result does not depend on the tiling or the thread count. The same sums as
// wind_primitives::add_batch (the GPU's), with two savings: only the rows and
// columns in a primitive's box are visited, and psi at the right corners of
// a cell is reused as the left corners of the next (psi is a pure function
// of the corner, so the bits are the same).
void CpuBackend::perturb_wind(const std::vector<wind_primitives::Batch>& batches) {
  namespace wp = wind_primitives;
  if (&batches != &last_batches_) last_batches_ = batches;
  for (const wp::Batch& b : batches) {
#pragma omp parallel num_threads(threads_)
    {
      std::vector<double> ux(static_cast<size_t>(g_.nx)), uy(static_cast<size_t>(g_.nx));
      std::vector<unsigned char> touched(static_cast<size_t>(g_.nx));
#pragma omp for schedule(static)
      for (int y = 0; y < g_.ny; ++y) {
        const int gy = g_.y0 + y;
        bool row = false;
        for (int k = 0; k < b.n; ++k) {
          const wp::Primitive& P = b.p[k];
          if (!wp::in_span(gy, P.by0, P.bh, P.gny)) continue;
          if (!row) {
            std::fill(ux.begin(), ux.end(), 0.0);
            std::fill(uy.begin(), uy.end(), 0.0);
            std::fill(touched.begin(), touched.end(), 0);
            row = true;
          }
          int prev = -2;
          double right0 = 0.0, right1 = 0.0;  // psi at (gx + 1, gy), (gx + 1, gy + 1)
          for (int x = 0; x < g_.nx; ++x) {
            const int gx = g_.x0 + x;
            if (!wp::in_span(gx, P.bx0, P.bw, P.gnx)) continue;
            const bool carry = prev == x - 1;
            const double p00 = carry ? right0 : wp::psi_at_corner(P, gx, gy);
            const double p01 = carry ? right1 : wp::psi_at_corner(P, gx, gy + 1);
            right0 = wp::psi_at_corner(P, gx + 1, gy);
            right1 = wp::psi_at_corner(P, gx + 1, gy + 1);
            prev = x;
            const wp::Velocity u = wp::curl_of_corners(p00, right0, p01, right1, P.cell_m);
            const size_t i = static_cast<size_t>(x);
            ux[i] += u.x;
            uy[i] += u.y;
            touched[i] = 1;
          }
        }
        if (!row) continue;
        float* wx = f_.wind_x.row(y);
        float* wy = f_.wind_y.row(y);
        for (int x = 0; x < g_.nx; ++x) {
          const size_t i = static_cast<size_t>(x);
          if (!touched[i]) continue;
          wx[x] = wx[x] + static_cast<float>(ux[i]);
          wy[x] = wy[x] + static_cast<float>(uy[i]);
        }
      }
    }
  }
}

}  // namespace erg::cpu
