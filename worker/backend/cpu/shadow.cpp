// SPDX-License-Identifier: Apache-2.0
// Wind shadow on the CPU (stages/wind_shadow.h).
//
// Most cells have no terrain within reach that rises at 10 degrees: a bound on
// the heights each block of cells can see upwind (the maximum over the blocks
// its march can reach; with cubic samples, which can overshoot what they read,
// raised by their overshoot over the range down to the minimum) settles them
// without marching.
#include <algorithm>

#include "backend/cpu/cpu_backend.h"
#include "backend/cpu/shadow_march.h"
#include "stages/echo_dunes.h"
#include "stages/wind_shadow.h"

namespace erg::cpu {

void CpuBackend::shadow() {
  const wind_shadow::Params& p = m_.shadow;
  const float* base = f_.height_m.data() + g_.at(0, 0);
  const int pitch = g_.pitch;
  constexpr int B = 8;
  // Maxima of B x B blocks of the padded height field (row maxima per block
  // first, a vectorisable pass; then across the block's rows).
  const int pbx = (pitch + B - 1) / B, pby = (g_.rows() + B - 1) / B;
  // Minima too for the cubic samples, which can overshoot what they read
  // (wind_shadow::sample_bound).
  const bool lows = p.cubic;
  block_max_.assign(static_cast<size_t>(pbx) * pby, -3.0e38f);
  block_min_.assign(lows ? block_max_.size() : 0, 3.0e38f);
  // Row r folded into the blocks' extremes `out` with pick (max or min).
  auto fold_row = [pitch](const float* r, float* out, auto pick) {
    for (int bx = 0; bx < pitch / B; ++bx) {
      float m = r[bx * B];
      for (int k = 1; k < B; ++k) m = pick(m, r[bx * B + k]);
      out[bx] = pick(out[bx], m);
    }
    for (int px = (pitch / B) * B; px < pitch; ++px) out[pitch / B] = pick(out[pitch / B], r[px]);
  };
  const auto higher = [](float a, float b) { return std::max(a, b); };
  const auto lower = [](float a, float b) { return std::min(a, b); };
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int by = 0; by < pby; ++by) {
    for (int py = by * B; py < std::min((by + 1) * B, g_.rows()); ++py) {
      const float* r = f_.height_m.data() + static_cast<size_t>(py) * pitch;
      fold_row(r, block_max_.data() + static_cast<size_t>(by) * pbx, higher);
      if (lows) fold_row(r, block_min_.data() + static_cast<size_t>(by) * pbx, lower);
    }
  }
  // A bound for each block of owned cells on every sample its marches can
  // take: from the blocks they can reach (`steps` cells, plus the samples'
  // footprint), taken along x, then along y.
  const int reach = p.steps + wind_shadow::footprint(p);
  const int obx = (g_.nx + B - 1) / B, oby = (g_.ny + B - 1) / B;
  auto span = [&](int i, int n) {
    return std::pair<int, int>{(i * B - reach + g_.halo) / B,
                               (std::min((i + 1) * B, n) - 1 + reach + g_.halo) / B};
  };
  // The extreme (pick: higher or lower; none: its identity) over the blocks
  // within reach.
  auto within_reach = [&](const std::vector<float>& blocks, auto pick, float none) {
    std::vector<float> along_x(static_cast<size_t>(pby) * obx);
    for (int by = 0; by < pby; ++by)
      for (int I = 0; I < obx; ++I) {
        const auto [x0, x1] = span(I, g_.nx);
        float m = none;
        for (int bx = x0; bx <= x1; ++bx) m = pick(m, blocks[static_cast<size_t>(by) * pbx + bx]);
        along_x[static_cast<size_t>(by) * obx + I] = m;
      }
    std::vector<float> out(static_cast<size_t>(oby) * obx, none);
    for (int J = 0; J < oby; ++J) {
      const auto [y0, y1] = span(J, g_.ny);
      for (int I = 0; I < obx; ++I) {
        float m = none;
        for (int by = y0; by <= y1; ++by) m = pick(m, along_x[static_cast<size_t>(by) * obx + I]);
        out[static_cast<size_t>(J) * obx + I] = m;
      }
    }
    return out;
  };
  bound_ = within_reach(block_max_, higher, -3.0e38f);
  if (lows) {
    const std::vector<float> least = within_reach(block_min_, lower, 3.0e38f);
    for (size_t k = 0; k < bound_.size(); ++k)
      bound_[k] = wind_shadow::sample_bound(bound_[k], least[k], p);
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
  shadow_valid_ = true;
  shadow_of_wind_ = true;
}

}  // namespace erg::cpu
