// Reptation on the GPU (stages/reptation.h), as backend/cpu/reptation.cpp:
// one gather pass into a second buffer (donor and receiver evaluate the same
// exchange() call, so no atomics are needed), then a swap.
#include "backend/cuda/cuda_backend.h"
#include "stages/reptation.h"

namespace erg::gpu {

namespace {

__global__ void reptation_kernel(TileGeom g, Offsets off, float k_r, const units_t* bedrock,
                                 const units_t* sand, const float* strength, units_t* next) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  const long long i = static_cast<long long>(g.at(x, y));
  const float l = g.cell_m;
  const units_t hi = bedrock[i] + sand[i];
  units_t delta = 0;
  for (int k = 0; k < 8; ++k) {
    const long long j = i + off.o[k];
    const units_t hj = bedrock[j] + sand[j];
    // The higher cell donates; both sides evaluate the same exchange.
    delta += reptation::exchange(hi, hj, strength[i], strength[j], sand[i], sand[j],
                                 l * neighbour(k).dist, k_r);
  }
  next[i] = sand[i] + delta;
}

}  // namespace

void CudaBackend::reptation() {
  if (m_.reptation_k <= 0.0f) return;
  fill_halo_periodic(bedrock_.get(), g_, Model::kHaloStencil);
  fill_halo_periodic(sand_.get(), g_, Model::kHaloStencil);
  fill_halo_periodic(reptation_.get(), g_, Model::kHaloStencil);
  const Launch l = owned_cells(g_);
  ERG_LAUNCH(reptation_kernel, l.grid, l.block, g_, neighbour_offsets(g_.pitch), m_.reptation_k,
             bedrock_.get(), sand_.get(), reptation_.get(), sand_next_.get());
  sand_.swap(sand_next_);
}

}  // namespace erg::gpu
