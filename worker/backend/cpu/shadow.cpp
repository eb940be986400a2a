// SPDX-License-Identifier: Apache-2.0
// Wind shadow on the CPU (stages/wind_shadow.h).
//
// Most cells have no terrain within reach that rises at 10 degrees: a bound on
// the heights each block of cells can see upwind (the maximum over the blocks
// its march can reach) settles them without marching.
#include <algorithm>

#include "backend/cpu/cpu_backend.h"
#include "stages/echo_dunes.h"
#include "stages/wind_shadow.h"

namespace erg::cpu {

namespace {

constexpr int kSegment = 64;

// Marches cells x0..x1-1 of row y step by step: step j for every cell, then
// step j + 1, so the inner loop vectorises (with gathers for the bilinear
// samples); stops once every cell is fully shadowed.
void march_segment(const float* base, int pitch, const float* wx, const float* wy, int x0, int x1,
                   int y, const wind_shadow::Params& p, float* __restrict out) {
  const int n = x1 - x0;
  float ux[kSegment], uy[kSegment], h0[kSegment], best[kSegment];
  bool calm[kSegment];
  for (int i = 0; i < n; ++i) {
    const wind_shadow::Upwind u = wind_shadow::upwind({wx[x0 + i], wy[x0 + i]});
    ux[i] = u.ux;
    uy[i] = u.uy;
    calm[i] = u.calm;
    h0[i] = base[static_cast<long>(y) * pitch + x0 + i];
    best[i] = -1e30f;
  }
  for (int j = 1; j <= p.steps; ++j) {
    for (int i = 0; i < n; ++i)
      best[i] = max_of(
          best[i], wind_shadow::angle(base, pitch, x0 + i, y, {ux[i], uy[i], false}, j, h0[i], p));
    float least = best[0];
    for (int i = 1; i < n; ++i) least = min_of(least, best[i]);
    if (least >= p.tan_max) break;  // every cell is at 1 already
  }
  for (int i = 0; i < n; ++i)
    out[x0 + i] = (calm[i] || p.steps <= 0) ? 0.0f : wind_shadow::from_angle(best[i], p);
}

}  // namespace

void CpuBackend::shadow() {
  const wind_shadow::Params& p = m_.shadow;
  const float* base = f_.height_m.data() + g_.at(0, 0);
  const int pitch = g_.pitch;
  constexpr int B = 8;
  // Maxima of B x B blocks of the padded height field (row maxima per block
  // first, a vectorisable pass; then across the block's rows).
  const int pbx = (pitch + B - 1) / B, pby = (g_.rows() + B - 1) / B;
  block_max_.assign(static_cast<size_t>(pbx) * pby, -3.0e38f);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int by = 0; by < pby; ++by) {
    float* out = block_max_.data() + static_cast<size_t>(by) * pbx;
    for (int py = by * B; py < std::min((by + 1) * B, g_.rows()); ++py) {
      const float* r = f_.height_m.data() + static_cast<size_t>(py) * pitch;
      for (int bx = 0; bx < pitch / B; ++bx) {
        float m = r[bx * B];
        for (int k = 1; k < B; ++k) m = std::max(m, r[bx * B + k]);
        out[bx] = std::max(out[bx], m);
      }
      for (int px = (pitch / B) * B; px < pitch; ++px)
        out[pitch / B] = std::max(out[pitch / B], r[px]);
    }
  }
  // A bound for each block of owned cells: the maximum over every block its
  // marches can reach (`steps` cells, plus one for the bilinear footprint),
  // taken along x, then along y.
  const int reach = p.steps + 1;
  const int obx = (g_.nx + B - 1) / B, oby = (g_.ny + B - 1) / B;
  auto span = [&](int i, int n) {
    return std::pair<int, int>{(i * B - reach + g_.halo) / B,
                               (std::min((i + 1) * B, n) - 1 + reach + g_.halo) / B};
  };
  std::vector<float> along_x(static_cast<size_t>(pby) * obx);
  for (int by = 0; by < pby; ++by)
    for (int I = 0; I < obx; ++I) {
      const auto [x0, x1] = span(I, g_.nx);
      float m = -3.0e38f;
      for (int bx = x0; bx <= x1; ++bx)
        m = std::max(m, block_max_[static_cast<size_t>(by) * pbx + bx]);
      along_x[static_cast<size_t>(by) * obx + I] = m;
    }
  bound_.assign(static_cast<size_t>(oby) * obx, -3.0e38f);
  for (int J = 0; J < oby; ++J) {
    const auto [y0, y1] = span(J, g_.ny);
    for (int I = 0; I < obx; ++I) {
      float m = -3.0e38f;
      for (int by = y0; by <= y1; ++by) m = std::max(m, along_x[static_cast<size_t>(by) * obx + I]);
      bound_[static_cast<size_t>(J) * obx + I] = m;
    }
  }
  // Segments of a row: settled by the bound, or marched step-major.
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4)
  for (int y = 0; y < g_.ny; ++y) {
    const float* h = f_.height_m.row(y);
    float* out = f_.shadow.row(y);
    for (int x0 = 0; x0 < g_.nx; x0 += kSegment) {
      const int x1 = std::min(x0 + kSegment, g_.nx);
      bool settled = true;
      for (int x = x0; x < x1 && settled; ++x)
        settled = wind_shadow::certainly_unshadowed(
            bound_[static_cast<size_t>(y / B) * obx + x / B], h[x], p);
      if (settled) {
        std::fill(out + x0, out + x1, 0.0f);
        continue;
      }
      march_segment(base, pitch, f_.wind_x.row(y), f_.wind_y.row(y), x0, x1, y, p, out);
    }
  }
  // Echo dunes: erosion and sticky cells in front of cliffs, from the same
  // heights (stages/echo_dunes.h).
  if (m_.echo.on) {
    const echo_dunes::Params e = m_.echo;
    const float* o_base = f_.obstacles.data() + g_.at(0, 0);
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4)
    for (int y = 0; y < g_.ny; ++y) {
      const float* wx = f_.wind_x.row(y);
      const float* wy = f_.wind_y.row(y);
      float* out = f_.echo.row(y);
      for (int x = 0; x < g_.nx; ++x)
        out[x] = echo_dunes::classify(base, o_base, pitch, x, y, {wx[x], wy[x]}, e);
    }
  }
}

}  // namespace erg::cpu
