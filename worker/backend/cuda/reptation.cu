// SPDX-License-Identifier: Apache-2.0
// Reptation on the GPU (stages/reptation.h), as backend/cpu/reptation.cpp:
// one gather pass into a second buffer (donor and receiver evaluate the same
// exchange() call, so no atomics are needed), then a swap.
#include "backend/cuda/cuda_backend.h"
#include "stages/reptation.h"

namespace erg::gpu {

namespace {

__global__ void reptation_kernel(TileGeom g, int grow, Offsets off, float k_r,
                                 const units_t* bedrock, const units_t* sand, const float* strength,
                                 const float* ob, units_t* next) {
  int x, y;
  if (!grown_cell(g, grow, x, y)) return;
  const long long i = static_cast<long long>(g.at(x, y));
  const float l = g.cell_m;
  const units_t hi = bedrock[i] + sand[i];
  units_t delta = 0;
  for (int k = 0; k < 8; ++k) {
    const long long j = i + off.o[k];
    const units_t hj = bedrock[j] + sand[j];
    // The higher cell donates; both sides evaluate the same exchange.
    delta += reptation::exchange_free(hi, hj, strength[i], strength[j], sand[i], sand[j],
                                      l * neighbour(k).dist, k_r, ob[i], ob[j]);
  }
  next[i] = sand[i] + delta;
}

}  // namespace

void CudaBackend::reptation() {
  // The layers and impact strengths come with the avalanching halo plus one
  // (fields::Reach::kReptation, one exchange before this stage, as on the
  // CPU); reptation runs on the tile grown by the avalanching halo.
  if (m_.reptation_k <= 0.0f) return;
  const int grow = m_.ghost_width(fields::Reach::kReptation) - 1;
  const Launch l = grown_cells(g_, grow);
  ERG_LAUNCH(reptation_kernel, l.grid, l.block, g_, grow, neighbour_offsets(g_.pitch),
             m_.reptation_k, d_.bedrock.get(), d_.sand.get(), d_.reptation.get(),
             d_.obstacles.get(), sand_next_.get());
  d_.sand.swap(sand_next_);
}

}  // namespace erg::gpu
