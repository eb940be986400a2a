// SPDX-License-Identifier: Apache-2.0
// Reptation on the CPU (stages/reptation.h): one gather pass, written out
// over the 8 neighbours so that it vectorises.
#include "stages/reptation.h"

#include "backend/cpu/cpu_backend.h"

namespace erg::cpu {

namespace {

// One row. A separate function with restrict-qualified outputs: inside an
// OpenMP region GCC does not vectorise this loop.
void reptation_row(const units_t* h, const units_t* s, const float* sr, const float* ob,
                   units_t* __restrict next, int nx, long pitch, float l, float k_r) {
  const float ld = l * kSqrt2;
  const long o0 = 1, o1 = pitch + 1, o2 = pitch, o3 = pitch - 1;  // kNeighbours order
  const long o4 = -1, o5 = -pitch - 1, o6 = -pitch, o7 = -pitch + 1;
  for (int x = 0; x < nx; ++x) {
    const units_t hx = h[x], sx = s[x];
    const float srx = sr[x];
    auto ex = [=](long o, float dist_m) {
      return reptation::exchange_free(hx, h[x + o], srx, sr[x + o], sx, s[x + o], dist_m, k_r,
                                      ob[x], ob[x + o]);
    };
    next[x] =
        sx + (((((((ex(o0, l) + ex(o1, ld)) + ex(o2, l)) + ex(o3, ld)) + ex(o4, l)) + ex(o5, ld)) +
               ex(o6, l)) +
              ex(o7, ld));
  }
}

}  // namespace

void CpuBackend::reptation() {
  // The layers and the impact strengths come with the avalanching halo plus
  // one (fields::Reach::kReptation, one exchange before this stage).
  // Reptation runs on the tile grown by the avalanching halo (its ghosts
  // computed exactly as their owners compute them), so the first avalanching
  // round needs no exchange.
  if (m_.reptation_k <= 0.0f) return;
  const int w = m_.ghost_width(fields::Reach::kReptation);
  const int e = w - 1;
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = -w; y < g_.ny + w; ++y) {
    const units_t* b = f_.bedrock.row(y);
    const units_t* s = f_.sand.row(y);
    units_t* h = height_units_.row(y);
    for (int x = -w; x < g_.nx + w; ++x) h[x] = b[x] + s[x];
  }
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = -e; y < g_.ny + e; ++y)
    reptation_row(height_units_.row(y) - e, f_.sand.row(y) - e, f_.reptation.row(y) - e,
                  f_.obstacles.row(y) - e, sand_next_.row(y) - e, g_.nx + 2 * e, g_.pitch,
                  g_.cell_m, m_.reptation_k);
  f_.sand.swap(sand_next_);
}

}  // namespace erg::cpu
