// Reptation on the CPU (stages/reptation.h): one gather pass, written out
// over the 8 neighbours so that it vectorises.
#include "stages/reptation.h"

#include "backend/cpu/cpu_backend.h"

namespace erg::cpu {

namespace {

// One row. A separate function with restrict-qualified outputs: inside an
// OpenMP region GCC does not vectorise this loop.
void reptation_row(const units_t* h, const units_t* s, const float* sr, units_t* __restrict next,
                   int nx, long pitch, float l, float k_r) {
  const float ld = l * kSqrt2;
  const long o0 = 1, o1 = pitch + 1, o2 = pitch, o3 = pitch - 1;  // kNeighbours order
  const long o4 = -1, o5 = -pitch - 1, o6 = -pitch, o7 = -pitch + 1;
  for (int x = 0; x < nx; ++x) {
    const units_t hx = h[x], sx = s[x];
    const float srx = sr[x];
    auto ex = [=](long o, float dist_m) {
      return reptation::exchange(hx, h[x + o], srx, sr[x + o], sx, s[x + o], dist_m, k_r);
    };
    next[x] =
        sx + (((((((ex(o0, l) + ex(o1, ld)) + ex(o2, l)) + ex(o3, ld)) + ex(o4, l)) + ex(o5, ld)) +
               ex(o6, l)) +
              ex(o7, ld));
  }
}

}  // namespace

void CpuBackend::reptation() {
  if (m_.reptation_k <= 0.0f) return;
  const int w = Model::kHaloStencil;
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y) {
    const units_t* b = bedrock_.row(y);
    const units_t* s = sand_.row(y);
    units_t* h = height_units_.row(y);
    for (int x = 0; x < g_.nx; ++x) h[x] = b[x] + s[x];
  }
  fill_halo_periodic(height_units_, w);
  fill_halo_periodic(sand_, w);
  fill_halo_periodic(reptation_, w);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = 0; y < g_.ny; ++y)
    reptation_row(height_units_.row(y), sand_.row(y), reptation_.row(y), sand_next_.row(y), g_.nx,
                  g_.pitch, g_.cell_m, m_.reptation_k);
  sand_.swap(sand_next_);
}

}  // namespace erg::cpu
