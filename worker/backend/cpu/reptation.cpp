// SPDX-License-Identifier: Apache-2.0
// Reptation on the CPU (stages/reptation.h): one gather pass, written out
// over the 8 neighbours so that it vectorises.
#include "stages/reptation.h"

#include <cstring>

#include "backend/cpu/cpu_backend.h"

namespace erg::cpu {

namespace {

// One row. A separate function with restrict-qualified outputs: inside an
// OpenMP region GCC does not vectorise this loop. The heights b + s are
// summed where they are read (no buffer of them: core/fields.h, Storage).
void reptation_row(const units_t* b, const units_t* s, const float* sr, const float* ob,
                   units_t* __restrict next, int nx, long pitch, float l, float k_r) {
  const float ld = l * kSqrt2;
  const long o0 = 1, o1 = pitch + 1, o2 = pitch, o3 = pitch - 1;  // kNeighbours order
  const long o4 = -1, o5 = -pitch - 1, o6 = -pitch, o7 = -pitch + 1;
  for (int x = 0; x < nx; ++x) {
    const units_t sx = s[x], hx = b[x] + sx;
    const float srx = sr[x];
    auto ex = [=](long o, float dist_m) {
      return reptation::exchange_free(hx, b[x + o] + s[x + o], srx, sr[x + o], sx, s[x + o], dist_m,
                                      k_r, ob[x], ob[x + o]);
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
  // The new sand goes to the shared work buffer (its wind is no longer
  // needed this step), then back into the sand on the grown tile: the
  // first avalanching round reads no farther.
  wind_valid_ = false;
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = -e; y < g_.ny + e; ++y)
    reptation_row(f_.bedrock.row(y) - e, f_.sand.row(y) - e, f_.reptation.row(y) - e,
                  f_.obstacles.row(y) - e, sand_next_.row(y) - e, g_.nx + 2 * e, g_.pitch,
                  g_.cell_m, m_.reptation_k);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int y = -e; y < g_.ny + e; ++y)
    std::memcpy(f_.sand.row(y) - e, sand_next_.row(y) - e,
                sizeof(units_t) * static_cast<std::size_t>(g_.nx + 2 * e));
}

}  // namespace erg::cpu
