// SPDX-License-Identifier: Apache-2.0
// Wind shadow on the GPU (stages/wind_shadow.h), as backend/cpu/shadow.cpp:
// one thread per owned cell marching upwind over the halo-filled heights.
#include "backend/cuda/cuda_backend.h"
#include "stages/echo_dunes.h"
#include "stages/wind_shadow.h"

namespace erg::gpu {

namespace {

__global__ void shadow_kernel(TileGeom g, wind_shadow::Params p, const float* h_base,
                              const float* wind_x, const float* wind_y, float* shadow) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  shadow[i] = wind_shadow::shadow(h_base, g.pitch, x, y, {wind_x[i], wind_y[i]}, p);
}

__global__ void echo_kernel(TileGeom g, echo_dunes::Params p, const float* h_base,
                            const float* o_base, const float* wind_x, const float* wind_y,
                            float* echo) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const std::size_t i = g.at(x, y);
  echo[i] = echo_dunes::classify(h_base, o_base, g.pitch, x, y, {wind_x[i], wind_y[i]}, p);
}

}  // namespace

void CudaBackend::shadow() {
  const Launch l = owned_cells(g_);
  // h_base points at local cell (0, 0), as wind_shadow::shadow expects.
  ERG_LAUNCH(shadow_kernel, l.grid, l.block, g_, m_.shadow, d_.height_m.get() + g_.at(0, 0),
             d_.wind_x.get(), d_.wind_y.get(), d_.shadow.get());
  if (m_.echo.on)
    ERG_LAUNCH(echo_kernel, l.grid, l.block, g_, m_.echo, d_.height_m.get() + g_.at(0, 0),
               d_.obstacles.get() + g_.at(0, 0), d_.wind_x.get(), d_.wind_y.get(), d_.echo.get());
}

}  // namespace erg::gpu
