// SPDX-License-Identifier: Apache-2.0
// The CPU backend's fast paths give the same bits as the plain per-cell
// stages/ bodies the GPU runs, on random inputs: the step-major shadow march
// and the bound that skips whole segments (backend/cpu/shadow_march.h,
// stages/wind_shadow.h), and the vectorised expected-mode scatter of
// saltation (backend/cpu/saltation_rows.h, stages/hop_landing.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "backend/cpu/saltation_rows.h"
#include "backend/cpu/shadow_march.h"
#include "core/grid.h"
#include "stages/wind_shadow.h"

namespace erg {
namespace {

TileGeom tile(int nx, int ny, int halo) {
  TileGeom g;
  g.nx = nx;
  g.ny = ny;
  g.halo = halo;
  g.pitch = nx + 2 * halo + 3;  // padded, as the backends' fields
  g.x0 = 17;
  g.y0 = 5;
  g.gnx = 4 * nx;
  g.gny = 3 * ny;
  g.cell_m = 2.0f;
  return g;
}

// Bit patterns, so that -0.0f and 0.0f (and NaN) are told apart.
std::uint32_t bits(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

wind_shadow::Params shadow_params(int steps, bool cubic) {
  wind_shadow::Params p{};
  p.steps = steps;
  p.cubic = cubic;
  p.cell_m = 2.0f;
  p.tan_min = 0.176f;  // 10 degrees
  p.tan_max = 0.268f;  // 15 degrees
  wind_shadow::finish(p);
  return p;
}

TEST(CpuFastPaths, StepMajorShadowMarchEqualsPerCellShadow) {
  std::mt19937 rng(12345);
  for (const bool cubic : {true, false})
    for (const int steps : {0, 1, 7, 20}) {
      const TileGeom g = tile(150, 23, steps + 2);  // 150: a short last segment
      const wind_shadow::Params p = shadow_params(steps, cubic);
      std::uniform_real_distribution<float> height(0.0f, 6.0f), wind(-3.0f, 3.0f);
      std::vector<float> h(g.size()), wx(g.size()), wy(g.size());
      for (float& v : h) v = height(rng);
      for (size_t i = 0; i < g.size(); ++i) {
        wx[i] = wind(rng);
        wy[i] = wind(rng);
        if (i % 37 == 0) wx[i] = wy[i] = 0.0f;  // calm cells
        if (i % 41 == 0) wy[i] = 0.0f;          // along an axis
      }
      const float* base = h.data() + g.at(0, 0);
      int marched = 0;
      for (int y = 0; y < g.ny; ++y) {
        std::vector<float> fast(static_cast<size_t>(g.nx), -7.0f);
        for (int x0 = 0; x0 < g.nx; x0 += cpu::kSegment)
          cpu::march_segment(base, g.pitch, wx.data() + g.at(0, y), wy.data() + g.at(0, y), x0,
                             std::min(x0 + cpu::kSegment, g.nx), y, p, fast.data());
        for (int x = 0; x < g.nx; ++x) {
          const size_t i = g.at(x, y);
          const float plain = wind_shadow::shadow(base, g.pitch, x, y, {wx[i], wy[i]}, p);
          ASSERT_EQ(bits(fast[static_cast<size_t>(x)]), bits(plain))
              << (cubic ? "cubic" : "bilinear") << " steps " << steps << " cell " << x << "," << y;
          marched += plain > 0.0f;
        }
      }
      if (steps > 0) {
        EXPECT_GT(marched, 0);  // the inputs do cast shadows
      }
    }
}

// The segment skipping: a cell the height bound settles is one the plain
// path gives exactly 0, on rough terrain whose bound barely settles it. A
// cubic sample overshoots what it reads, so its bound is raised
// (wind_shadow::sample_bound); without that raise the test fails (a cell
// is settled whose march finds an angle).
TEST(CpuFastPaths, ShadowBoundSkipsOnlyUnshadowedCells) {
  for (const bool cubic : {true, false}) {
    std::mt19937 rng(777);
    const int steps = 12;
    const TileGeom g = tile(96, 40, steps + 2);
    const wind_shadow::Params p = shadow_params(steps, cubic);
    std::uniform_real_distribution<float> height(0.0f, 1.0f), wind(-2.0f, 2.0f);
    std::vector<float> h(g.size()), wx(g.size()), wy(g.size());
    for (size_t i = 0; i < g.size(); ++i) {
      h[i] = 100.0f + 0.05f * height(rng);
      wx[i] = wind(rng);
      wy[i] = wind(rng);
    }
    const auto [lo, hi] = std::minmax_element(h.begin(), h.end());
    const float bound = wind_shadow::sample_bound(*hi, *lo, p);
    const float* base = h.data() + g.at(0, 0);
    int settled = 0;
    for (int y = 0; y < g.ny; ++y)
      for (int x = 0; x < g.nx; ++x) {
        const size_t i = g.at(x, y);
        if (!wind_shadow::certainly_unshadowed(bound, h[i], p)) continue;
        ++settled;
        ASSERT_EQ(bits(wind_shadow::shadow(base, g.pitch, x, y, {wx[i], wy[i]}, p)), bits(0.0f))
            << (cubic ? "cubic" : "bilinear") << " cell " << x << "," << y;
      }
    EXPECT_GT(settled, g.nx * g.ny / 3);
  }
}

saltation::Params saltation_params(bool stochastic) {
  saltation::Params p{};
  p.slab_units = 1000.0f;
  p.hop_time_s = 1.3f;
  p.max_hop_m = 9.0f;
  p.cell_m = 2.0f;
  p.deposit_on_sand = 0.6f;
  p.deposit_on_bedrock = 0.4f;
  p.stochastic = stochastic;
  return p;
}

struct Airborne {
  TileGeom g;
  std::vector<units_t> air;
  std::vector<float> wx, wy, obstacles, heights;
};
Airborne random_airborne(std::uint32_t seed) {
  std::mt19937 rng(seed);
  Airborne a{tile(70, 19, 6), {}, {}, {}, {}, {}};
  const std::size_t n = a.g.size();
  a.air.assign(n, 0);
  a.wx.assign(n, 0.0f);
  a.wy.assign(n, 0.0f);
  a.obstacles.assign(n, 0.0f);
  a.heights.assign(n, 0.0f);
  std::uniform_real_distribution<float> wind(-5.0f, 5.0f), height(0.0f, 3.0f);
  std::uniform_int_distribution<units_t> amount(0, 1'000'000'007);
  for (std::size_t i = 0; i < n; ++i) {
    a.air[i] = i % 5 == 0 ? 0 : amount(rng);
    a.wx[i] = i % 23 == 0 ? 0.0f : wind(rng);
    a.wy[i] = wind(rng);
    a.heights[i] = height(rng);
  }
  return a;
}

// Every row scattered by the plain path (land_hop per cell), with the
// obstacle walk on or off.
std::vector<units_t> scatter_plain(Airborne a, const saltation::Params& p, bool obstacles) {
  std::vector<units_t> landed(a.g.size(), 0);
  for (int y = 0; y < a.g.ny; ++y)
    cpu::scatter_row(a.air.data() + a.g.at(0, y), a.wx.data() + a.g.at(0, y),
                     a.wy.data() + a.g.at(0, y), a.g, y, 99, 42, p, obstacles,
                     a.heights.data() + a.g.at(0, 0), a.obstacles.data() + a.g.at(0, 0),
                     landed.data());
  return landed;
}

// The vectorised pass against land_hop per cell, with the hop's deflection
// down the slope off and on (the slope of random heights, the wind in every
// direction; physics.hop_slope_deflection).
void expect_vectorised_scatter_equals_plain(float slope_k) {
  Airborne a = random_airborne(2024);
  saltation::Params p = saltation_params(false);
  p.slope_k = slope_k;
  const std::vector<units_t> plain = scatter_plain(a, p, false);
  std::vector<units_t> fast(a.g.size(), 0);
  std::vector<long> target(static_cast<size_t>(a.g.nx));
  std::vector<units_t> parts(saltation::kLandingCells * static_cast<size_t>(a.g.nx));
  units_t owned_total = 0;  // what is in flight (scatter_plain took a copy)
  for (int y = 0; y < a.g.ny; ++y)
    for (int x = 0; x < a.g.nx; ++x) owned_total += a.air[a.g.at(x, y)];
  for (int y = 0; y < a.g.ny; ++y) {
    const auto split = slope_k > 0.0f ? cpu::split_row<true> : cpu::split_row<false>;
    split(a.air.data() + a.g.at(0, y), a.wx.data() + a.g.at(0, y), a.wy.data() + a.g.at(0, y),
          a.heights.data() + a.g.at(0, y), a.g.nx, y, static_cast<long>(a.g.at(0, 0)), a.g.pitch, p,
          target.data(), parts.data());
    cpu::add_splits(target.data(), parts.data(), a.g.nx, a.g.pitch, fast.data());
  }
  EXPECT_EQ(fast, plain);
  units_t landed_total = 0;
  for (units_t v : plain) landed_total += v;
  EXPECT_EQ(landed_total, owned_total);  // every owned unit lands somewhere
  EXPECT_GT(owned_total, 0);
}

TEST(CpuFastPaths, VectorisedExpectedScatterEqualsPlainLanding) {
  expect_vectorised_scatter_equals_plain(0.0f);
}

TEST(CpuFastPaths, VectorisedDeflectedScatterEqualsPlainLanding) {
  expect_vectorised_scatter_equals_plain(0.34f);
  // The deflection moved sand: the same airborne sand lands elsewhere.
  Airborne a = random_airborne(2024);
  saltation::Params p = saltation_params(false);
  const std::vector<units_t> straight = scatter_plain(a, p, false);
  p.slope_k = 0.34f;
  EXPECT_NE(scatter_plain(a, p, false), straight);
}

// The landing kernel (stages/saltation.h, spread()) has the same mean and
// covariance whatever the wind's angle to the grid: the landing point, and
// 1/4 cell^2 along and across the wind, for the expected split of one hop
// and for the stochastic mode's draws over many cells. (The bilinear split
// it replaced had 0 across the wind at 0 degrees, 0.14 at 23 degrees.)
struct Moments {
  double mx = 0, my = 0, along = 0, across = 0, cross = 0;
};
Moments landing_moments(const std::vector<units_t>& landed, const TileGeom& g, int sx, int sy,
                        double deg) {
  const double c = std::cos(deg * M_PI / 180.0), s = std::sin(deg * M_PI / 180.0);
  double total = 0;
  Moments m;
  for (int y = -g.halo; y < g.ny + g.halo; ++y)
    for (int x = -g.halo; x < g.nx + g.halo; ++x) {
      const double w = static_cast<double>(landed[g.at(x, y)]);
      total += w;
      m.mx += w * (x - sx);
      m.my += w * (y - sy);
    }
  m.mx /= total;
  m.my /= total;
  for (int y = -g.halo; y < g.ny + g.halo; ++y)
    for (int x = -g.halo; x < g.nx + g.halo; ++x) {
      const double w = static_cast<double>(landed[g.at(x, y)]) / total;
      const double dx = x - sx - m.mx, dy = y - sy - m.my;
      const double a = dx * c + dy * s, b = -dx * s + dy * c;
      m.along += w * a * a;
      m.across += w * b * b;
      m.cross += w * a * b;
    }
  return m;
}

TEST(CpuFastPaths, LandingSpreadIsTheSameAtEveryWindAngle) {
  for (const bool stochastic : {false, true}) {
    const saltation::Params p = saltation_params(stochastic);
    const double hop = 5.0 * 1.3 / 2.0;  // |w| hop_time_s in 2 m cells: 3.25
    for (const double deg : {0.0, 1.79, 23.0, 37.0, 45.0, 161.0}) {
      const float wx = static_cast<float>(5.0 * std::cos(deg * M_PI / 180.0));
      const float wy = static_cast<float>(5.0 * std::sin(deg * M_PI / 180.0));
      // Expected: one cell's hop; stochastic: every cell of a 16 x 16 block
      // (each draws its own cell), moments about each source.
      const int n = stochastic ? 16 : 1;
      TileGeom g = tile(64, 64, 8);
      std::vector<units_t> landed(g.size(), 0);
      double mx = 0, my = 0, along = 0, across = 0, cross = 0;
      for (int y = 24; y < 24 + n; ++y)
        for (int x = 24; x < 24 + n; ++x) {
          std::vector<units_t> one(g.size(), 0), air(static_cast<size_t>(g.nx), 0);
          std::vector<float> rx(static_cast<size_t>(g.nx), wx), ry(static_cast<size_t>(g.nx), wy);
          air[static_cast<size_t>(x)] = units_t{1} << 40;
          cpu::scatter_row(air.data(), rx.data(), ry.data(), g, y, 7, 3, p, false, nullptr, nullptr,
                           one.data());
          const Moments m = landing_moments(one, g, x, y, deg);
          mx += m.mx / (n * n);
          my += m.my / (n * n);
          if (stochastic) {  // moments of the draws about the hop's end
            const double ex = hop * std::cos(deg * M_PI / 180.0) - m.mx;
            const double ey = hop * std::sin(deg * M_PI / 180.0) - m.my;
            const double c = std::cos(deg * M_PI / 180.0), s = std::sin(deg * M_PI / 180.0);
            const double a = ex * c + ey * s, b = -ex * s + ey * c;
            along += a * a / (n * n);
            across += b * b / (n * n);
            cross += a * b / (n * n);
          } else {
            along = m.along;
            across = m.across;
            cross = m.cross;
          }
        }
      const double tol = stochastic ? 0.07 : 1e-6;  // 256 draws: the sampling error
      EXPECT_NEAR(mx, hop * std::cos(deg * M_PI / 180.0), stochastic ? 0.08 : 1e-6) << deg;
      EXPECT_NEAR(my, hop * std::sin(deg * M_PI / 180.0), stochastic ? 0.08 : 1e-6) << deg;
      EXPECT_NEAR(along, 0.25, tol) << stochastic << " " << deg;
      EXPECT_NEAR(across, 0.25, tol) << stochastic << " " << deg;
      EXPECT_NEAR(cross, 0.0, tol) << stochastic << " " << deg;
    }
  }
}

// Without an obstacle in reach the obstacle walk lands every unit where the
// plain hop does (so the CPU may skip it), in both modes; with obstacles it
// moves sand and still conserves it.
TEST(CpuFastPaths, ObstacleWalkWithoutObstaclesEqualsPlainHop) {
  for (const bool stochastic : {false, true}) {
    Airborne a = random_airborne(stochastic ? 5u : 6u);
    const saltation::Params p = saltation_params(stochastic);
    EXPECT_EQ(scatter_plain(a, p, true), scatter_plain(a, p, false)) << stochastic;
    for (int y = 3; y < 9; ++y)
      for (int x = 10; x < 30; ++x) {
        a.obstacles[a.g.at(x, y)] = 2.5f;
        a.air[a.g.at(x, y)] = 0;  // obstacles hold no sand
      }
    const std::vector<units_t> blocked = scatter_plain(a, p, true);
    EXPECT_NE(blocked, scatter_plain(a, p, false));
    units_t sum_blocked = 0, sum_free = 0;
    for (units_t v : blocked) sum_blocked += v;
    for (units_t v : scatter_plain(a, p, false)) sum_free += v;
    EXPECT_EQ(sum_blocked, sum_free);
    for (int y = 3; y < 9; ++y)
      for (int x = 10; x < 30; ++x) EXPECT_EQ(blocked[a.g.at(x, y)], 0) << x << "," << y;
  }
}

}  // namespace
}  // namespace erg
