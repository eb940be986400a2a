// SPDX-License-Identifier: Apache-2.0
// Surface wind on the GPU: venturi and multi-scale warping
// (stages/venturi.h, stages/wind_warping.h), as backend/cpu/wind.cpp:
// heights in metres, exact coarse block sums, spectral Gaussian gradients on
// the coarse grid (cuFFT, double), then the per-cell wind; then the local
// wind primitives (stages/wind_primitives.h).
#include <vector>

#include "backend/cuda/cuda_backend.h"
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

// Spectrum times the Gaussian (normalisation folded in) times the spectral
// derivative along `axis`, into `work`, exactly as cpu::CoarseSmoother: physical
// wave numbers, the Nyquist mode of the differentiated axis dropped.
__global__ void spectral_gradient_kernel(CoarseGrid c, const cufftDoubleComplex* spectrum,
                                         const double* gauss, cufftDoubleComplex* work, int axis) {
  const int hx = c.nx / 2 + 1;
  const std::size_t k = flat_index();
  if (k >= static_cast<std::size_t>(hx) * c.ny) return;
  const int j = static_cast<int>(k / hx), i = static_cast<int>(k % hx);
  const wind_warping::Mode m =
      wind_warping::gradient_mode(c, i, j, axis, spectrum[k].x, spectrum[k].y, gauss[k]);
  work[k].x = m.re;
  work[k].y = m.im;
}

__global__ void to_float_kernel(const double* in, float* out, std::size_t n) {
  const std::size_t k = flat_index();
  if (k < n) out[k] = static_cast<float>(in[k]);
}

__global__ void wind_kernel(TileGeom g, CoarseGrid c, Vec2 a, float venturi_k,
                            wind_warping::Params wp, const float* h, const float* gx0,
                            const float* gy0, const float* gx1, const float* gy1, float* wind_x,
                            float* wind_y) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  const int gx = g.x0 + x, gy = g.y0 + y;
  const Vec2 v = venturi::wind(a, h[i], venturi_k);
  const Vec2 gl{wind_warping::sample_coarse(gx0, c.nx, c.ny, c.cx, c.cy, gx, gy),
                wind_warping::sample_coarse(gy0, c.nx, c.ny, c.cx, c.cy, gx, gy)};
  const Vec2 gs{wind_warping::sample_coarse(gx1, c.nx, c.ny, c.cx, c.cy, gx, gy),
                wind_warping::sample_coarse(gy1, c.nx, c.ny, c.cx, c.cy, gx, gy)};
  const Vec2 w = wind_warping::warp(v, gl, gs, wp);
  wind_x[i] = w.x;
  wind_y[i] = w.y;
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
  const std::size_t n = static_cast<std::size_t>(c.nx) * c.ny;
  const std::size_t nc = static_cast<std::size_t>(c.nx / 2 + 1) * c.ny;
  ERG_CUFFT_CHECK(cufftExecD2Z(forward_.get(), coarse_h_.get(), spectrum_.get()));
  const Launch ls = flat(nc), lr = flat(n);
  for (int s = 0; s < 2; ++s) {
    for (int axis = 0; axis < 2; ++axis) {
      // The spectrum stays intact: Z2D may overwrite its input, which is work_.
      ERG_LAUNCH(spectral_gradient_kernel, ls.grid, ls.block, c, spectrum_.get(), gauss_[s].get(),
                 work_.get(), axis);
      ERG_CUFFT_CHECK(cufftExecZ2D(inverse_.get(), work_.get(), coarse_h_.get()));
      float* out = axis == 0 ? grad_x_[s].get() : grad_y_[s].get();
      ERG_LAUNCH(to_float_kernel, lr.grid, lr.block, coarse_h_.get(), out, n);
    }
  }
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
  std::vector<double> mine(coarse_mine_.size()), all;
  ERG_CUDA_CHECK(
      cudaMemcpy(mine.data(), coarse_mine_.get(), coarse_mine_.bytes(), cudaMemcpyDeviceToHost));
  ex_.gather_coarse(mine, all);
  ERG_CUDA_CHECK(
      cudaMemcpy(coarse_h_.get(), all.data(), coarse_h_.bytes(), cudaMemcpyHostToDevice));
  coarse_gradients();

  ERG_LAUNCH(wind_kernel, cells.grid, cells.block, g_, c, a, m_.venturi_k, m_.warp,
             d_.height_m.get(), grad_x_[0].get(), grad_y_[0].get(), grad_x_[1].get(),
             grad_y_[1].get(), d_.wind_x.get(), d_.wind_y.get());
}

}  // namespace erg::gpu
