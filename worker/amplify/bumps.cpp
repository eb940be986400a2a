// SPDX-License-Identifier: Apache-2.0
#include "amplify/bumps.h"

#include <algorithm>
#include <cmath>

#include "amplify/sampling.h"
#include "core/philox.h"

namespace erg::amplify {

using detail::wrap;

namespace {

struct Site {
  double x = 0, y = 0;  // continuous coarse-cell coordinates (cell i spans [i, i+1))
  double height = 0;    // metres
};

// Two blended point primitives [P19 Fig. 13], distances in coarse cells.
double bump_profile(double dx, double dy, double ux, double uy, double r) {
  // Windward mound, centred a third of a radius upwind.
  const double mx = dx + 0.33 * r * ux, my = dy + 0.33 * r * uy;
  const double mound = std::exp(-(mx * mx + my * my) / (r * r));
  if (ux == 0 && uy == 0) return mound;
  // Lee tail: half height, 1.5 r along the wind, 0.6 r across, centred 1.2 r downwind.
  const double along = dx * ux + dy * uy - 1.2 * r;
  const double across = -dx * uy + dy * ux;
  const double tail =
      0.5 * std::exp(-along * along / (2.25 * r * r) - across * across / (0.36 * r * r));
  return std::max(mound, tail);
}

}  // namespace

std::vector<float> sand_bumps(const AmplifyInput& in, const Region& region, int upsample,
                              const AmplifyParams& p) {
  const int k = upsample;
  const int onx = region.w * k, ony = region.h * k;
  std::vector<float> out(static_cast<size_t>(onx) * ony, 0.0f);
  const double r = p.bump_radius_m() / in.cell_size_m;  // coarse cells
  const double reach = 4.0 * r;                         // the tail ends by 1.2 r + 2 * 1.5 r
  const int margin = static_cast<int>(std::ceil(reach)) + 1;
  const int sites_per_cell = static_cast<int>(std::ceil(p.bump_plants_per_cell()));
  const bool obstacles = !in.obstacles.empty();
  if ((sites_per_cell == 0 || p.bump_height_m() <= 0) &&
      (!obstacles || p.obstacle_bump_height_m() <= 0))
    return out;

  auto sand_factor = [&](size_t c) {
    const double m = p.ripple_min_sand_m();
    return m > 0 ? std::clamp(in.sand[c] / m, 0.0, 1.0) : (in.sand[c] > 0 ? 1.0 : 0.0);
  };
  auto place = [&](const Site& s, size_t c) {
    const double wx = in.wind[2 * c], wy = in.wind[2 * c + 1];
    const double speed = std::hypot(wx, wy);
    const double ux = speed > 1e-6 ? wx / speed : 0, uy = speed > 1e-6 ? wy / speed : 0;
    // Fine cells within reach (unwrapped coordinates of the output grid).
    const int i0 = std::max(0, static_cast<int>(std::floor((s.x - reach - region.x0) * k)));
    const int i1 = std::min(onx - 1, static_cast<int>(std::ceil((s.x + reach - region.x0) * k)));
    const int j0 = std::max(0, static_cast<int>(std::floor((s.y - reach - region.y0) * k)));
    const int j1 = std::min(ony - 1, static_cast<int>(std::ceil((s.y + reach - region.y0) * k)));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const double dx = region.x0 + (i + 0.5) / k - s.x;
        const double dy = region.y0 + (j + 0.5) / k - s.y;
        const double b = s.height * bump_profile(dx, dy, ux, uy, r);
        float& o = out[static_cast<size_t>(j) * onx + i];
        o = std::max(o, static_cast<float>(b));
      }
  };

  // Unwrapped coarse cells covering the region and the reach of a bump; a
  // cell is read at its wrapped index, so a region spanning the torus gets
  // the bumps of the cells across its edges.
  for (int cy = region.y0 - margin; cy < region.y0 + region.h + margin; ++cy)
    for (int cx = region.x0 - margin; cx < region.x0 + region.w + margin; ++cx) {
      const int ix = wrap(cx, in.nx), iy = wrap(cy, in.ny);
      const size_t c = static_cast<size_t>(iy) * in.nx + ix;
      const double sand = sand_factor(c);
      if (sand <= 0) continue;
      const double v = in.vegetation[c];
      for (int s = 0; s < sites_per_cell && v > 0; ++s) {
        Philox4 ctr;
        ctr.v[0] = static_cast<std::uint32_t>(c);
        ctr.v[1] = static_cast<std::uint32_t>(static_cast<std::uint64_t>(c) >> 32);
        ctr.v[2] = 0x4e41424bu;  // "NABK"
        ctr.v[3] = static_cast<std::uint32_t>(s);
        const Philox4 rnd = philox4x32_10(ctr, static_cast<std::uint32_t>(in.seed),
                                          static_cast<std::uint32_t>(in.seed >> 32));
        // Site s exists with probability v (times the fractional last site).
        const double share = std::min(1.0, p.bump_plants_per_cell() - s);
        if (u01(rnd.v[0]) >= v * share) continue;
        place(Site{cx + u01(rnd.v[1]), cy + u01(rnd.v[2]), p.bump_height_m() * v * sand}, c);
      }
      if (obstacles) {
        const double o = std::clamp(static_cast<double>(in.obstacles[c]), 0.0, 1.0);
        if (o > 0) place(Site{cx + 0.5, cy + 0.5, p.obstacle_bump_height_m() * o * sand}, c);
      }
    }
  return out;
}

}  // namespace erg::amplify
