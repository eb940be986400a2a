// SPDX-License-Identifier: Apache-2.0
#include "amplify/ripples.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "amplify/sampling.h"
#include "core/philox.h"

namespace erg::amplify {

using detail::bilinear;
using detail::wrap;

namespace {

// Drops `amount` at the off-lattice point (x, y) of the periodic grid, split
// bilinearly over the four cells around it (oblique winds land between cells).
void drop(std::vector<double>& h, int nx, int ny, double x, double y, double amount) {
  const double fx = std::floor(x), fy = std::floor(y);
  const double ax = x - fx, ay = y - fy;
  int i0 = static_cast<int>(fx), j0 = static_cast<int>(fy);
  int i1 = i0 + 1, j1 = j0 + 1;
  if (i0 < 0 || i1 >= nx) i0 = wrap(i0, nx), i1 = wrap(i1, nx);
  if (j0 < 0 || j1 >= ny) j0 = wrap(j0, ny), j1 = wrap(j1, ny);
  h[static_cast<size_t>(j0) * nx + i0] += amount * (1 - ax) * (1 - ay);
  h[static_cast<size_t>(j0) * nx + i1] += amount * ax * (1 - ay);
  h[static_cast<size_t>(j1) * nx + i0] += amount * (1 - ax) * ay;
  h[static_cast<size_t>(j1) * nx + i1] += amount * ax * ay;
}

}  // namespace

std::vector<PastWind> past_winds(const std::vector<Vec2>& history) {
  std::vector<PastWind> out;
  if (history.empty()) return {PastWind{}};
  const Vec2 now = history.back();
  const double now_speed = std::hypot(now.x, now.y);
  const double now_dir = std::atan2(now.y, now.x);
  for (const Vec2& a : history) {
    const double speed = std::hypot(a.x, a.y);
    PastWind w;
    if (now_speed > 1e-6) {
      // Same local deflection as now, turned with the high-altitude wind.
      const double turn = std::atan2(a.y, a.x) - now_dir;
      w.cos_turn = static_cast<float>(std::cos(turn));
      w.sin_turn = static_cast<float>(std::sin(turn));
      w.gain = static_cast<float>(speed / now_speed);
    } else {
      w.gain = 0;  // calm now: the snapshot's local wind says nothing of the past
    }
    out.push_back(w);
  }
  return out;
}

std::vector<float> ripple_relief(const RippleGrid& g, const std::vector<PastWind>& winds,
                                 const AmplifyParams& p) {
  const int nx = g.nx, ny = g.ny;
  const size_t n = static_cast<size_t>(nx) * ny;
  std::vector<double> h(n), next(n);
  // Initial height: seeded noise in [-0.05, 0.05) [ON00 2(1): "random numbers"].
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const std::uint64_t gx = static_cast<std::uint64_t>(wrap(g.gx0 + i, g.gnx));
      const std::uint64_t gy = static_cast<std::uint64_t>(wrap(g.gy0 + j, g.gny));
      Philox4 c;
      c.v[0] = static_cast<std::uint32_t>(gx);
      c.v[1] = static_cast<std::uint32_t>(gy);
      c.v[2] = 0x52495050u;  // "RIPP": a stream of its own
      c.v[3] = 0;
      const Philox4 r = philox4x32_10(c, static_cast<std::uint32_t>(g.seed),
                                      static_cast<std::uint32_t>(g.seed >> 32));
      h[static_cast<size_t>(j) * nx + i] = 0.1 * (u01(r.v[0]) - 0.5);
    }

  const double q = p.ripple_lift();
  const double b = p.ripple_hop_height_gain();
  const double hop_per_mps = p.ripple_hop_cells_per_mps();
  const double hop_max = p.ripple_hop_max_cells();
  const double creep = p.ripple_creep();
  const double reptation = p.ripple_reptation();
  const double rep_hop = p.ripple_reptation_hop_cells();
  const double tan_impact = std::tan(p.ripple_impact_angle_deg() * std::numbers::pi / 180);
  const double golden = 0.61803398874989485;
  const size_t nwinds = std::max<size_t>(1, winds.size());

  // The local wind as speed and unit direction, once (an iteration only
  // turns and scales it).
  std::vector<double> speed0(n), ux0(n), uy0(n);
  for (size_t c = 0; c < n; ++c) {
    const double wx = g.wind[2 * c], wy = g.wind[2 * c + 1];
    speed0[c] = std::hypot(wx, wy);
    ux0[c] = speed0[c] > 1e-6 ? wx / speed0[c] : 0;
    uy0[c] = speed0[c] > 1e-6 ? wy / speed0[c] : 0;
  }

  for (std::int64_t it = 0; it < p.ripple_iterations(); ++it) {
    // The wind of this iteration: a low-discrepancy walk over the history.
    const double frac = std::fmod(static_cast<double>(it + 1) * golden, 1.0);
    const PastWind pw = winds.empty()
                            ? PastWind{}
                            : winds[std::min(nwinds - 1, static_cast<size_t>(frac * nwinds))];
    const double ct = pw.cos_turn, st = pw.sin_turn;
    // Saltation [ON00 2(1)]: H(x) -= q; H(x + L) += q, L = L0 + b H(x). The
    // landing point is off the lattice for an oblique wind: split bilinearly.
    // A scatter, in row-major order: the same sums on every run.
    next = h;
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        const size_t c = static_cast<size_t>(j) * nx + i;
        const double lift = q * g.mobility[c];
        const double speed = pw.gain * speed0[c];
        if (lift <= 0 || speed < 1e-6) continue;
        const double l0 = std::min(hop_per_mps * speed, hop_max);
        if (l0 <= 0) continue;
        const double dx = ct * ux0[c] - st * uy0[c], dy = st * ux0[c] + ct * uy0[c];
        const double hop = std::clamp(l0 + b * h[c], 0.0, 2 * hop_max);
        next[c] -= lift;
        drop(next, nx, ny, i + hop * dx, j + hop * dy, lift);
        // Reptation splash [A87]: the saltating rain comes down at the impact
        // angle theta onto the face between this cell and the point one cell
        // upwind. Per unit of horizontal area a face rising downwind at slope
        // tan(alpha) intercepts 1 + tan(alpha) / tan(theta) times the
        // flat-bed impacts, a lee face steeper than theta none (impact
        // shadow); each impact pushes grains a short hop downwind.
        if (reptation <= 0) continue;
        const double rise = h[c] - bilinear(h, nx, ny, i - dx, j - dy);
        const double impacts = std::max(0.0, 1 + rise / tan_impact);
        const double splash = reptation * lift * impacts;
        if (splash <= 0) continue;
        next[c] -= splash;
        drop(next, nx, ny, i + rep_hop * dx, j + rep_hop * dy, splash);
      }
    }

    // Creep [ON00 2(1)]: relaxation by gravity as diffusion (Nishimori &
    // Ouchi's isotropic 9-point weights). A gather: rows in parallel give
    // the same bits on any thread count.
#pragma omp parallel for schedule(static) if (n >= (size_t{1} << 18))
    for (int j = 0; j < ny; ++j) {
      const size_t jm = static_cast<size_t>(wrap(j - 1, ny)) * nx;
      const size_t j0 = static_cast<size_t>(j) * nx;
      const size_t jp = static_cast<size_t>(wrap(j + 1, ny)) * nx;
      for (int i = 0; i < nx; ++i) {
        const int im = wrap(i - 1, nx), ip = wrap(i + 1, nx);
        const double nn = next[jm + i] + next[jp + i] + next[j0 + im] + next[j0 + ip];
        const double nnn = next[jm + im] + next[jm + ip] + next[jp + im] + next[jp + ip];
        h[j0 + i] = next[j0 + i] + creep * (nn / 6 + nnn / 12 - next[j0 + i]);
      }
    }
  }

  // Keep the ripples, not the drift of sand between open and sheltered
  // cells: H minus its mean over a window of several ripple wavelengths
  // (three periodic box blurs of radius 2 * L0max + 2, close to a Gaussian).
  double l0_max = 0;
  for (const PastWind& w : winds) l0_max = std::max(l0_max, static_cast<double>(w.gain));
  double speed_max = 0;
  for (size_t c = 0; c < n; ++c)
    speed_max = std::max(speed_max, std::hypot(static_cast<double>(g.wind[2 * c]),
                                               static_cast<double>(g.wind[2 * c + 1])));
  l0_max = std::min(hop_per_mps * speed_max * std::max(1.0, l0_max), hop_max);
  const int radius = static_cast<int>(std::ceil(2 * l0_max)) + 2;
  std::vector<double> low = h, tmp(n);
  for (int pass = 0; pass < 3; ++pass) {
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        double sum = 0;
        for (int d = -radius; d <= radius; ++d)
          sum += low[static_cast<size_t>(j) * nx + wrap(i + d, nx)];
        tmp[static_cast<size_t>(j) * nx + i] = sum / (2 * radius + 1);
      }
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        double sum = 0;
        for (int d = -radius; d <= radius; ++d)
          sum += tmp[static_cast<size_t>(wrap(j + d, ny)) * nx + i];
        low[static_cast<size_t>(j) * nx + i] = sum / (2 * radius + 1);
      }
  }
  for (size_t c = 0; c < n; ++c) h[c] -= low[c];

  // Scale: standard deviation p.ripple_height_m over the mobile sand.
  double wsum = 0, mean = 0;
  for (size_t c = 0; c < n; ++c) {
    wsum += g.mobility[c];
    mean += g.mobility[c] * h[c];
  }
  std::vector<float> out(n, 0.0f);
  if (wsum <= 1e-9) return out;
  mean /= wsum;
  double var = 0;
  for (size_t c = 0; c < n; ++c) var += g.mobility[c] * (h[c] - mean) * (h[c] - mean);
  const double sd = std::sqrt(var / wsum);
  if (!(sd > 1e-12)) return out;
  const double scale = p.ripple_height_m() / sd;
  for (size_t c = 0; c < n; ++c) out[c] = static_cast<float>(g.mobility[c] * scale * (h[c] - mean));
  return out;
}

}  // namespace erg::amplify
