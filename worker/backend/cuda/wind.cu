// SPDX-License-Identifier: Apache-2.0
// Surface wind on the GPU: venturi and multi-scale warping
// (stages/venturi.h, stages/wind_warping.h), as backend/cpu/wind.cpp:
// heights in metres, exact coarse block sums, the tile's coarse window
// (Exchange::coarse_window), truncated Gaussians along y then x and central
// differences on it (double, the CPU's bits), then the per-cell wind; then
// the local wind primitives (stages/wind_primitives.h).
#include <vector>

#include "backend/cuda/cuda_backend.h"
#include "stages/shear_stress.h"
#include "stages/venturi.h"
#include "stages/wind_primitives.h"
#include "stages/wind_warping.h"

namespace erg::gpu {

namespace {

constexpr int kCoarseThreads = kRowThreads;  // block_sum needs kRowThreads

__global__ void heights_kernel(TileGeom g, const units_t* bedrock, const units_t* sand,
                               const float* ob, float* h) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  // The wind sees obstacles as terrain [BR04 4.3] (stages/obstacles.h).
  h[i] = units_to_m(bedrock[i] + sand[i]) + ob[i];
}

// One block per coarse cell (I, J) of this tile (tiles are aligned to coarse
// cells), blocks in row-major order: the exact sum of b + s over its fine
// cells (128-bit, as on the CPU), then the mean height in metres.
__global__ void coarse_sum_kernel(TileGeom g, CoarseGrid c, int tile_cnx, const units_t* bedrock,
                                  const units_t* sand, const float* ob, double* coarse_h) {
  __shared__ total_t red[kCoarseThreads];
  const int I = static_cast<int>(blockIdx.x % tile_cnx),
            J = static_cast<int>(blockIdx.x / tile_cnx);
  const long long cells = static_cast<long long>(c.cx) * c.cy;
  total_t sum = 0;
  for (long long t = threadIdx.x; t < cells; t += kCoarseThreads) {
    const int y = J * c.cy + static_cast<int>(t / c.cx);
    const int x = I * c.cx + static_cast<int>(t % c.cx);
    const std::size_t i = g.at(x, y);
    sum += bedrock[i] + sand[i] + obstacles::height_units(ob[i]);
  }
  sum = block_sum(sum, red);
  if (threadIdx.x == 0)
    coarse_h[static_cast<std::size_t>(J) * tile_cnx + I] =
        static_cast<double>(sum) * kUnitM / (static_cast<double>(c.cx) * c.cy);
}

// The pass along y at every (column, row) of `rows`, i.e. wind_warping::rows_at.
__global__ void rows_kernel(wind_warping::TileWindow t, const double* window, const double* w,
                            int r, double* rows) {
  const std::size_t k = flat_index();
  const int wx = t.wx();
  if (k >= static_cast<std::size_t>(t.tcny + 4) * wx) return;
  const int j = static_cast<int>(k / wx), i = static_cast<int>(k % wx);
  rows[k] = wind_warping::rows_at(window, t, w, r, i, j);
}

// The pass along x: wind_warping::smooth_at.
__global__ void smooth_kernel(wind_warping::TileWindow t, const double* rows, const double* w,
                              int r, double* smooth) {
  const std::size_t k = flat_index();
  const int sx = t.tcnx + 4;
  if (k >= static_cast<std::size_t>(t.tcny + 4) * sx) return;
  const int j = static_cast<int>(k / sx), i = static_cast<int>(k % sx);
  smooth[k] = wind_warping::smooth_at(rows, t, w, r, i, j);
}

// Central differences: wind_warping::gradient_at.
__global__ void gradient_kernel(wind_warping::TileWindow t, const double* smooth, double dx_m,
                                double dy_m, float* gx, float* gy) {
  const std::size_t k = flat_index();
  const int n = t.tcnx + 2;
  if (k >= static_cast<std::size_t>(t.tcny + 2) * n) return;
  const int j = static_cast<int>(k / n), i = static_cast<int>(k % n);
  const Vec2 g = wind_warping::gradient_at(smooth, t, dx_m, dy_m, i, j);
  gx[k] = g.x;
  gy[k] = g.y;
}

// e . grad h and e_perp . grad h at the window's inner cells:
// shear_stress::slope_at.
__global__ void shear_slope_kernel(wind_warping::TileWindow t, const double* window, double ex,
                                   double ey, double delta_m, double* slope, double* perp) {
  const std::size_t k = flat_index();
  const int wx = t.wx(), wy = t.wy();
  if (k >= static_cast<std::size_t>(wx) * wy) return;
  const int j = static_cast<int>(k / wx), i = static_cast<int>(k % wx);
  const bool inner = i > 0 && i < wx - 1 && j > 0 && j < wy - 1;
  slope[k] = inner ? shear_stress::slope_at(window, wx, ex, ey, delta_m, i, j) : 0.0;
  perp[k] = inner ? shear_stress::slope_at(window, wx, -ey, ex, delta_m, i, j) : 0.0;
}

// tau1 / tau0 and tau_y / tau0 at the tile's coarse cells -1 .. tcn:
// shear_stress::perturbation_at and shear_stress::lateral_at.
__global__ void shear_tau_kernel(wind_warping::TileWindow t, const double* slope,
                                 const double* perp, const double* window, shear_stress::TapsView k,
                                 shear_stress::TapsView c, shear_stress::TapsView cp,
                                 shear_stress::Params p, float* tau, float* tau_y) {
  const std::size_t q = flat_index();
  const int n = t.tcnx + 2;
  if (q >= static_cast<std::size_t>(t.tcny + 2) * n) return;
  const int j = static_cast<int>(q / n), i = static_cast<int>(q % n);
  tau[q] =
      shear_stress::perturbation_at(slope, window, t.wx(), k, c, p, t.hx - 1 + i, t.hy - 1 + j);
  tau_y[q] = shear_stress::lateral_at(perp, window, t.wx(), k, cp, p, t.hx - 1 + i, t.hy - 1 + j);
}

// tau, tau_y: tau1 / tau0 and tau_y / tau0 at the coarse cells (shear stress
// over relief), or null.
__global__ void wind_kernel(TileGeom g, CoarseGrid c, int gnx, Vec2 a, float venturi_k,
                            wind_warping::Params wp, const float* h, const float* gx0,
                            const float* gy0, const float* gx1, const float* gy1, const float* tau,
                            const float* tau_y, float* wind_x, float* wind_y) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  const int gx = g.x0 + x, gy = g.y0 + y;
  const Vec2 v = venturi::wind(a, h[i], venturi_k);
  // The tile's gradient arrays, gnx wide (coarse cells -1 .. tcnx).
  const wind_warping::Axis ax = wind_warping::coarse_axis(gx, c.cx, g.x0 / c.cx);
  const wind_warping::Axis ay = wind_warping::coarse_axis(gy, c.cy, g.y0 / c.cy);
  const Vec2 gl{wind_warping::sample_at(gx0, gnx, ax, ay),
                wind_warping::sample_at(gy0, gnx, ax, ay)};
  const Vec2 gs{wind_warping::sample_at(gx1, gnx, ax, ay),
                wind_warping::sample_at(gy1, gnx, ax, ay)};
  const Vec2 w = wind_warping::warp(v, gl, gs, wp);
  // The surface wind carries u*: turned to the stress's direction and scaled
  // by the square root of its magnitude (shear_stress::surface_wind).
  const Vec2 s = tau != nullptr
                     ? shear_stress::surface_wind(wind_warping::sample_at(tau, gnx, ax, ay),
                                                  wind_warping::sample_at(tau_y, gnx, ax, ay), w)
                     : w;
  wind_x[i] = s.x;
  wind_y[i] = s.y;
}

// One batch of wind primitives added at every owned cell, from its global
// index only (as the CPU: wind_primitives::add_batch).
__global__ void perturb_kernel(TileGeom g, wind_primitives::Batch b, float* wind_x, float* wind_y) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  const Vec2 w = wind_primitives::add_batch({wind_x[i], wind_y[i]}, b, g.x0 + x, g.y0 + y);
  wind_x[i] = w.x;
  wind_y[i] = w.y;
}

}  // namespace

void CudaBackend::perturb_wind(const std::vector<wind_primitives::Batch>& batches) {
  const Launch cells = owned_cells(g_);
  for (const wind_primitives::Batch& b : batches)
    ERG_LAUNCH(perturb_kernel, cells.grid, cells.block, g_, b, d_.wind_x.get(), d_.wind_y.get());
}

void CudaBackend::coarse_gradients() {
  const CoarseGrid& c = m_.coarse;
  const wind_warping::TileWindow t = tw_;
  const Launch lr = flat(static_cast<std::size_t>(t.tcny + 4) * t.wx());
  const Launch ls = flat(static_cast<std::size_t>(t.tcny + 4) * (t.tcnx + 4));
  const Launch lg = flat(static_cast<std::size_t>(t.tcny + 2) * (t.tcnx + 2));
  for (int s = 0; s < 2; ++s) {
    ERG_LAUNCH(rows_kernel, lr.grid, lr.block, t, window_.get(), ky_[s].get(), c.radius_y[s],
               rows_.get());
    ERG_LAUNCH(smooth_kernel, ls.grid, ls.block, t, rows_.get(), kx_[s].get(), c.radius_x[s],
               smooth_.get());
    ERG_LAUNCH(gradient_kernel, lg.grid, lg.block, t, smooth_.get(), c.cx * c.cell_m,
               c.cy * c.cell_m, grad_x_[s].get(), grad_y_[s].get());
  }
}

bool CudaBackend::shear_field(Vec2 a) {
  const shear_stress::Params p = m_.shear;
  if (!p.on) return false;
  // The taps go to the device when the direction changes.
  const double ex0 = shear_kernel_.ex, ey0 = shear_kernel_.ey;
  const int taps0 = shear_kernel_.taps;
  if (!shear_kernel_.aim(a, p)) return false;
  const shear_stress::Kernel& k = shear_kernel_;
  if (taps0 == 0 || k.ex != ex0 || k.ey != ey0) {
    const std::size_t n = static_cast<std::size_t>(k.taps);
    if (n > 0) {
      ERG_CUDA_CHECK(
          cudaMemcpy(shear_k_.get(), k.k.data(), n * sizeof(double), cudaMemcpyHostToDevice));
      ERG_CUDA_CHECK(
          cudaMemcpy(shear_du_.get(), k.du.data(), n * sizeof(int), cudaMemcpyHostToDevice));
      ERG_CUDA_CHECK(
          cudaMemcpy(shear_dv_.get(), k.dv.data(), n * sizeof(int), cudaMemcpyHostToDevice));
    }
    const std::size_t nc = static_cast<std::size_t>(k.basis.n);
    if (shear_c_.size() != nc) {  // the basis is built with the first direction
      shear_c_.reset(nc);
      shear_cp_.reset(nc);
      shear_cdu_.reset(nc);
      shear_cdv_.reset(nc);
    }
    ERG_CUDA_CHECK(
        cudaMemcpy(shear_c_.get(), k.c.data(), nc * sizeof(double), cudaMemcpyHostToDevice));
    ERG_CUDA_CHECK(
        cudaMemcpy(shear_cp_.get(), k.cp.data(), nc * sizeof(double), cudaMemcpyHostToDevice));
    ERG_CUDA_CHECK(
        cudaMemcpy(shear_cdu_.get(), k.basis.du.data(), nc * sizeof(int), cudaMemcpyHostToDevice));
    ERG_CUDA_CHECK(
        cudaMemcpy(shear_cdv_.get(), k.basis.dv.data(), nc * sizeof(int), cudaMemcpyHostToDevice));
  }
  const wind_warping::TileWindow t = tw_;
  const Launch ls = flat(static_cast<std::size_t>(t.wx()) * t.wy());
  const Launch lt = flat(static_cast<std::size_t>(t.tcny + 2) * (t.tcnx + 2));
  ERG_LAUNCH(shear_slope_kernel, ls.grid, ls.block, t, window_.get(), k.ex, k.ey,
             m_.coarse.cx * m_.coarse.cell_m, shear_slope_.get(), shear_slope_perp_.get());
  const shear_stress::TapsView kd{shear_k_.get(), shear_du_.get(), shear_dv_.get(), k.taps};
  const shear_stress::TapsView cd{shear_c_.get(), shear_cdu_.get(), shear_cdv_.get(), k.basis.n};
  const shear_stress::TapsView cpd{shear_cp_.get(), shear_cdu_.get(), shear_cdv_.get(), k.basis.n};
  ERG_LAUNCH(shear_tau_kernel, lt.grid, lt.block, t, shear_slope_.get(), shear_slope_perp_.get(),
             window_.get(), kd, cd, cpd, p, shear_tau_.get(), shear_tau_y_.get());
  return true;
}

void CudaBackend::heights() {
  const CoarseGrid& c = m_.coarse;
  const Launch cells = owned_cells(g_);
  // Heights in metres at the owned cells (the step fills the ghosts the
  // shadow march reads).
  ERG_LAUNCH(heights_kernel, cells.grid, cells.block, g_, d_.bedrock.get(), d_.sand.get(),
             d_.obstacles.get(), d_.height_m.get());
  // Exact block sums of this tile's coarse cells; every tile gets the whole
  // coarse grid (the same integer sums whatever the tiling).
  const int tcnx = g_.nx / c.cx, tcny = g_.ny / c.cy;
  ERG_LAUNCH(coarse_sum_kernel, dim3(static_cast<unsigned>(tcnx * tcny)), dim3(kCoarseThreads), g_,
             c, tcnx, d_.bedrock.get(), d_.sand.get(), d_.obstacles.get(), coarse_mine_.get());
}

void CudaBackend::wind(Vec2 a) {
  const CoarseGrid& c = m_.coarse;
  const Launch cells = owned_cells(g_);
  std::vector<double> mine(coarse_mine_.size());
  ERG_CUDA_CHECK(
      cudaMemcpy(mine.data(), coarse_mine_.get(), coarse_mine_.bytes(), cudaMemcpyDeviceToHost));
  ex_.coarse_window(mine, tw_.tcnx, tw_.tcny, tw_.hx, tw_.hy, window_host_);
  ERG_CUDA_CHECK(
      cudaMemcpy(window_.get(), window_host_.data(), window_.bytes(), cudaMemcpyHostToDevice));
  coarse_gradients();
  const bool sheared = shear_field(a);
  const float* tau = sheared ? shear_tau_.get() : nullptr;
  const float* tau_y = sheared ? shear_tau_y_.get() : nullptr;

  ERG_LAUNCH(wind_kernel, cells.grid, cells.block, g_, c, tw_.tcnx + 2, a, m_.venturi_k, m_.warp,
             d_.height_m.get(), grad_x_[0].get(), grad_y_[0].get(), grad_x_[1].get(),
             grad_y_[1].get(), tau, tau_y, d_.wind_x.get(), d_.wind_y.get());
}

}  // namespace erg::gpu
