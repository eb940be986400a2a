// Wind shadow on the CPU (stages/wind_shadow.h).
//
// Most cells have no terrain within reach that rises at 10 degrees: a bound on
// the heights each block of cells can see upwind (the maximum over the blocks
// its march can reach) settles them without marching.
#include <algorithm>

#include "backend/cpu/cpu_backend.h"
#include "stages/wind_shadow.h"

namespace erg::cpu {

void CpuBackend::shadow() {
  const wind_shadow::Params p = m_.shadow;
  const float* base = height_m_.data() + g_.at(0, 0);
  const int pitch = g_.pitch;
  constexpr int B = 8;
  // Maxima of B x B blocks of the padded height field.
  const int pbx = (g_.pitch + B - 1) / B, pby = (g_.rows() + B - 1) / B;
  block_max_.assign(static_cast<size_t>(pbx) * pby, -3.0e38f);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int by = 0; by < pby; ++by)
    for (int py = by * B; py < std::min((by + 1) * B, g_.rows()); ++py) {
      const float* r = height_m_.data() + static_cast<size_t>(py) * pitch;
      for (int bx = 0; bx < pbx; ++bx) {
        float m = block_max_[static_cast<size_t>(by) * pbx + bx];
        for (int px = bx * B; px < std::min((bx + 1) * B, pitch); ++px) m = std::max(m, r[px]);
        block_max_[static_cast<size_t>(by) * pbx + bx] = m;
      }
    }
  // The march from a cell reaches at most `steps` cells away, plus one for
  // the bilinear footprint.
  const int reach = p.steps + 1;
  const int obx = (g_.nx + B - 1) / B;
  auto bound = [&](int I, int J) {
    const int x0 = (I * B - reach + g_.halo) / B, x1 = (std::min((I + 1) * B, g_.nx) - 1 + reach + g_.halo) / B;
    const int y0 = (J * B - reach + g_.halo) / B, y1 = (std::min((J + 1) * B, g_.ny) - 1 + reach + g_.halo) / B;
    float m = -3.0e38f;
    for (int by = y0; by <= y1; ++by)
      for (int bx = x0; bx <= x1; ++bx) m = std::max(m, block_max_[static_cast<size_t>(by) * pbx + bx]);
    return m;
  };
  // Rows vary in cost (marching and early exits): dynamic chunks.
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 8)
  for (int y = 0; y < g_.ny; ++y) {
    const float* wx = wind_x_.row(y);
    const float* wy = wind_y_.row(y);
    const float* h = height_m_.row(y);
    float* out = shadow_.row(y);
    for (int I = 0; I < obx; ++I) {
      const float hmax = bound(I, y / B);
      for (int x = I * B; x < std::min((I + 1) * B, g_.nx); ++x)
        out[x] = wind_shadow::certainly_unshadowed(hmax, h[x], p)
                     ? 0.0f
                     : wind_shadow::shadow(base, pitch, x, y, {wx[x], wy[x]}, p);
    }
  }
}

}  // namespace erg::cpu
