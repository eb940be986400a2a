// Wind shadow on the CPU (stages/wind_shadow.h).
#include "backend/cpu/cpu_backend.h"
#include "stages/wind_shadow.h"

namespace erg::cpu {

void CpuBackend::shadow() {
  const wind_shadow::Params p = m_.shadow;
  const float* base = height_m_.data() + g_.at(0, 0);
  const int pitch = g_.pitch;
  // Rows vary in cost (early exit in steep lee areas): dynamic chunks.
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 8)
  for (int y = 0; y < g_.ny; ++y) {
    const float* wx = wind_x_.row(y);
    const float* wy = wind_y_.row(y);
    float* out = shadow_.row(y);
    for (int x = 0; x < g_.nx; ++x) out[x] = wind_shadow::shadow(base, pitch, x, y, {wx[x], wy[x]}, p);
  }
}

}  // namespace erg::cpu
