// Reptation on the CPU (stages/reptation.h): one gather pass.
#include "backend/cpu/cpu_backend.h"
#include "stages/reptation.h"

namespace erg::cpu {

void CpuBackend::reptation() {
  if (m_.reptation_k <= 0.0f) return;
  fill_halo_periodic(bedrock_, Model::kHaloStencil);
  fill_halo_periodic(sand_, Model::kHaloStencil);
  fill_halo_periodic(reptation_, Model::kHaloStencil);
  const float k_r = m_.reptation_k;
  const float l = g_.cell_m;
  const int pitch = g_.pitch;
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y) {
    const units_t* b = bedrock_.row(y);
    const units_t* s = sand_.row(y);
    const float* sr = reptation_.row(y);
    units_t* next = sand_next_.row(y);
    for (int x = 0; x < g_.nx; ++x) {
      const units_t hi = b[x] + s[x];
      units_t delta = 0;
      for (int k = 0; k < 8; ++k) {
        const long o = static_cast<long>(kNeighbours[k].dy) * pitch + kNeighbours[k].dx;
        const units_t hj = b[x + o] + s[x + o];
        const float dist_m = l * kNeighbours[k].dist;
        // The higher cell donates; both sides evaluate the same call.
        if (hi > hj) delta -= reptation::transfer(hi - hj, dist_m, sr[x], sr[x + o], s[x], k_r);
        else if (hj > hi) delta += reptation::transfer(hj - hi, dist_m, sr[x + o], sr[x], s[x + o], k_r);
      }
      next[x] = s[x] + delta;
    }
  }
  sand_.swap(sand_next_);
}

}  // namespace erg::cpu
