// SPDX-License-Identifier: Apache-2.0
// Multi-scale wind warping on the coarse grid ([P19] 4.2, [N24] 3.3,
// stages/wind_warping.h):
// - the CPU's vectorised passes give the bits of the shared per-cell
//   functions (rows_at, smooth_at, gradient_at) that the CUDA backend runs;
// - the smoothed gradient of a sinusoid matches the analytic Gaussian
//   smoothing (the truncated kernel and central differences are accurate);
// - the coarse cell depends on the model's lengths only;
// - a 1024 m periodic terrain repeated 4 x 4 on a 4096 m torus gives, on
//   every copy, the bits of the wind on the 1024 m torus (the smoothing is
//   local: no domain-size dependence).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "backend/backend.h"
#include "backend/cpu/cpu_backend.h"
#include "core/units.h"
#include "dist/exchange.h"
#include "sim/model.h"
#include "sim/state.h"
#include "sim_test_util.h"
#include "stages/wind_warping.h"

namespace {

namespace ww = erg::wind_warping;

erg::CoarseGrid grid_of(int gnx, int gny, double cell_m) {
  return ww::coarse_grid(gnx, gny, cell_m, 100.0, 25.0);  // the default radii 200 m and 50 m
}

// A deterministic pseudo-random window (SplitMix64).
std::vector<double> random_window(std::size_t n, std::uint64_t seed) {
  std::vector<double> v(n);
  for (double& x : v) {
    std::uint64_t z = (seed += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    x = static_cast<double>(z >> 11) * 0x1.0p-53 * 20.0 - 10.0;
  }
  return v;
}

TEST(WindWarping, CpuPassesGiveTheBitsOfTheSharedPerCellFunctions) {
  const erg::CoarseGrid c = grid_of(256, 192, 1.0);
  const int tcnx = 24, tcny = 17;  // a tile narrower than its halo
  erg::cpu::CoarseSmoother smoother(c, tcnx, tcny);
  const ww::TileWindow t = smoother.tile();
  const std::vector<double> window = random_window(static_cast<std::size_t>(t.wx()) * t.wy(), 42);
  std::vector<float> gx[2], gy[2];
  smoother.gradients(window, gx, gy, 2);
  const double dx = c.cx * c.cell_m, dy = c.cy * c.cell_m;
  for (int s = 0; s < 2; ++s) {
    std::vector<double> kx(2 * static_cast<std::size_t>(c.radius_x[s]) + 1),
        ky(2 * static_cast<std::size_t>(c.radius_y[s]) + 1);
    ww::gaussian_kernel(c.sigma_m[s], dx, c.radius_x[s], kx.data());
    ww::gaussian_kernel(c.sigma_m[s], dy, c.radius_y[s], ky.data());
    // As the CUDA kernels do: every cell of every pass.
    std::vector<double> rows(static_cast<std::size_t>(tcny + 4) * t.wx());
    for (int j = 0; j < tcny + 4; ++j)
      for (int i = 0; i < t.wx(); ++i)
        rows[static_cast<std::size_t>(j) * t.wx() + i] =
            ww::rows_at(window.data(), t, ky.data(), c.radius_y[s], i, j);
    std::vector<double> smooth(static_cast<std::size_t>(tcny + 4) * (tcnx + 4));
    for (int j = 0; j < tcny + 4; ++j)
      for (int i = 0; i < tcnx + 4; ++i)
        smooth[static_cast<std::size_t>(j) * (tcnx + 4) + i] =
            ww::smooth_at(rows.data(), t, kx.data(), c.radius_x[s], i, j);
    int differ = 0;
    for (int j = 0; j < tcny + 2; ++j)
      for (int i = 0; i < tcnx + 2; ++i) {
        const erg::Vec2 g = ww::gradient_at(smooth.data(), t, dx, dy, i, j);
        const std::size_t k = static_cast<std::size_t>(j) * (tcnx + 2) + i;
        differ += (g.x != gx[s][k]) + (g.y != gy[s][k]);
      }
    EXPECT_EQ(differ, 0) << "scale " << s;
  }
}

// h = A sin(2 pi x / L): the Gaussian of sigma smooths it to
// A exp(-2 pi^2 sigma^2 / L^2) sin(2 pi x / L), whose gradient is known.
TEST(WindWarping, SmoothedGradientOfASinusoidMatchesTheGaussian) {
  const int n = 1024;  // 1 m cells: coarse cells of 4 m, 256 of them
  const erg::CoarseGrid c = grid_of(n, n, 1.0);
  ASSERT_EQ(c.cx, 4);
  const int tcn = c.nx;
  erg::cpu::CoarseSmoother smoother(c, tcn, tcn);
  const ww::TileWindow t = smoother.tile();
  const double pi = 3.14159265358979323846, L = 256.0, A = 3.0;  // 256 m wavelength
  std::vector<double> window(static_cast<std::size_t>(t.wx()) * t.wy());
  for (int j = 0; j < t.wy(); ++j)
    for (int i = 0; i < t.wx(); ++i) {
      // The block mean of A sin over the coarse cell (exact average).
      const double x0 = (i - t.hx) * 4.0, x1 = x0 + 4.0;
      const double mean =
          A * L / (2 * pi) * (std::cos(2 * pi * x0 / L) - std::cos(2 * pi * x1 / L)) / 4.0;
      window[static_cast<std::size_t>(j) * t.wx() + i] = mean;
    }
  std::vector<float> gx[2], gy[2];
  smoother.gradients(window, gx, gy, 1);
  for (int s = 0; s < 2; ++s) {
    const double sigma = c.sigma_m[s];
    // The block mean multiplies the amplitude by sinc(4 m / L).
    const double box = std::sin(pi * 4.0 / L) / (pi * 4.0 / L);
    const double amp = A * box * std::exp(-2 * pi * pi * sigma * sigma / (L * L)) * 2 * pi / L;
    double worst = 0;
    for (int j = 0; j < tcn + 2; ++j)
      for (int i = 0; i < tcn + 2; ++i) {
        const double x = (i - 1 + 0.5) * 4.0;  // the coarse cell's centre
        const double want = amp * std::cos(2 * pi * x / L);
        const std::size_t k = static_cast<std::size_t>(j) * (tcn + 2) + i;
        worst = std::max(worst, std::abs(gx[s][k] - want));
        EXPECT_NEAR(gy[s][k], 0.0, 1e-6 * amp);
      }
    // Central differences: relative error (k delta)^2 / 6 = 1.6e-3 at 4 m on
    // 256 m; the 4-sigma truncation adds < 1e-4 of the amplitude.
    EXPECT_LT(worst, 5e-3 * amp) << "scale " << s << " amplitude " << amp;
  }
}

TEST(WindWarping, CoarseCellsDependOnTheModelLengthsOnly) {
  for (int n : {64, 512, 1024, 4096, 65536}) {
    const erg::CoarseGrid c = grid_of(n, n, 1.0);
    EXPECT_EQ(c.cx, 4) << n;
    EXPECT_EQ(c.radius_x[0], 100) << n;  // 4 sigma = 400 m in 4 m cells
    EXPECT_EQ(c.radius_x[1], 25) << n;
    EXPECT_EQ(c.halo_x, 102) << n;
    EXPECT_EQ(c.nx, n / 4) << n;
  }
  EXPECT_EQ(ww::coarse_factor(0.25, 6.25), 16);
  EXPECT_EQ(ww::coarse_factor(2.0, 6.25), 2);
  EXPECT_EQ(ww::coarse_factor(10.0, 6.25), 1);
}

// The wind of a 1024 m torus (2 m cells) and of the same terrain repeated
// 4 x 4 on a 4096 m torus.
std::vector<std::vector<float>> wind_on(int n, int period) {
  const std::string json = R"({"domain": {"nx": )" + std::to_string(n) + R"(, "ny": )" +
                           std::to_string(n) + R"(, "cell_size_m": 2.0},
       "wind": {"constant": {"speed_mps": 5}}})";
  const erg::v1::JobSpec spec = erg::test::spec_from(json);
  const erg::Model m = erg::make_model(spec, n, n, 0, 0);
  erg::dist::PeriodicExchange ex;
  std::unique_ptr<erg::Backend> b = erg::make_backend(erg::BackendKind::kCpu, m, 2, ex);
  erg::TileState s;
  s.allocate(m.tile);
  const double pi = 3.14159265358979323846;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      // Periodic over `period` cells: dunes of three wavelengths, oblique.
      const double u = 2 * pi * (x % period) / period, v = 2 * pi * (y % period) / period;
      const double h = 6 * std::sin(u + 2 * v) + 3 * std::cos(3 * u - v) +
                       1.5 * std::sin(8 * u) * std::cos(5 * v) + 10;
      s.units[erg::fields::kBedrock](x, y) = erg::m_to_units(h);
    }
  b->upload(s);
  b->heights();
  b->wind({5.0f, 2.0f});
  std::vector<float> wx, wy;
  b->download_owned(erg::fields::kWindX, wx);
  b->download_owned(erg::fields::kWindY, wy);
  return {wx, wy};
}

TEST(WindWarping, ARepeatedTerrainGivesTheWindOfItsTorusOnEveryCopy) {
  const int small = 512, big = 2048;  // 1024 m and 4096 m at 2 m cells
  const auto one = wind_on(small, small);
  const auto many = wind_on(big, small);
  for (int f = 0; f < 2; ++f) {
    int differ = 0;
    for (int y = 0; y < big; ++y)
      for (int x = 0; x < big; ++x)
        differ += many[f][static_cast<std::size_t>(y) * big + x] !=
                  one[f][static_cast<std::size_t>(y % small) * small + (x % small)];
    EXPECT_EQ(differ, 0) << (f == 0 ? "wind_x" : "wind_y") << ": cells that differ";
  }
  // The warping did act: the venturi wind keeps its direction, the warped
  // one turns along the relief.
  double turn = 0;
  for (std::size_t k = 0; k < one[0].size(); ++k)
    turn = std::max(turn, std::abs(std::atan2(one[1][k], one[0][k]) - std::atan2(2.0, 5.0)));
  EXPECT_GT(turn, 1e-3) << "radians";
}

}  // namespace
