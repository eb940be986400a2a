// SPDX-License-Identifier: Apache-2.0
// Physical units (docs/physical-units.md): the wind as u* or U(z) with z0,
// the fluid threshold, the flat-bed flux against the flux law through the
// measured time per step, and a wind rose's drift against Fryberger & Dean
// 1979's DP, RDP and RDD from the same law.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "sim/calibration.h"
#include "sim/model.h"
#include "sim_test_util.h"
#include "stages/saltation.h"
#include "stages/shear_stress.h"
#include "wind/physics.h"
#include "wind/regime.h"

namespace erg {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A physical-mode job on 1 m cells: flat sand, a constant u*.
std::string job_json(const std::string& wind, const std::string& extra = "") {
  return R"({"domain": {"nx": 64, "ny": 64, "cell_size_m": 1},
             "layers": {"sand": {"constant": 2}},
             "wind": )" +
         wind + extra + "}";
}

TEST(PhysicalUnits, ThresholdIsBagnolds) {
  const auto spec = test::spec_from(
      job_json(R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4}})"));
  const physics::Sand s = physics::sand_of(spec);
  // u_t = 0.1 sqrt((2650 - 1.225) / 1.225 * 9.81 * 0.00025) [Bagnold 1941].
  EXPECT_NEAR(physics::threshold(s), 0.1 * std::sqrt(2648.775 / 1.225 * 9.81 * 0.00025), 1e-12);
  EXPECT_NEAR(physics::threshold(s), 0.2303, 5e-4);
  EXPECT_EQ(physics::flux_mass(s, 0.99 * physics::threshold(s)), 0.0);
  EXPECT_GT(physics::flux_mass(s, 1.01 * physics::threshold(s)), 0.0);
}

TEST(PhysicalUnits, LawOfTheWall) {
  // U(10 m) = 8 m/s over z0 = 1 mm: u* = 0.4 * 8 / ln(10 / 0.001).
  const auto spec = test::spec_from(job_json(
      R"({"speed_is": "WIND_AT_HEIGHT", "height_m": 10, "roughness_m": 0.001,
          "constant": {"speed_mps": 8, "direction_deg": 30}})"));
  EXPECT_NEAR(wind::shear_velocity_at(spec, 0), 0.4 * 8 / std::log(1e4), 1e-6);
  // z0 = 0: d / 30.
  const auto spec2 =
      test::spec_from(job_json(R"({"speed_is": "WIND_AT_HEIGHT", "constant": {"speed_mps": 8}})"));
  EXPECT_NEAR(wind::shear_velocity_at(spec2, 0), 0.4 * 8 / std::log(10 / (0.00025 / 30)), 1e-6);
  // Model units: no u*.
  const auto legacy = test::spec_from(job_json(R"({"constant": {"speed_mps": 8}})"));
  EXPECT_EQ(wind::shear_velocity_at(legacy, 0), 0.0);
}

TEST(PhysicalUnits, MixedSpeedKindsAreRejected) {
  erg::v1::JobSpec spec = job::parse_json(
      job_json(R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4}})",
               R"(, "events": [{"step": 5, "wind": {"constant": {"speed_mps": 6}}}])"),
      "t");
  job::apply_defaults(spec);
  const auto problems = job::validate(spec);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("events[0].wind.speed_is = MODEL but wind.speed_is = SHEAR_VELOCITY"),
            std::string::npos)
      << problems[0];
}

// Across u* = 1.1 u_t to 3 u_t the measured flat-bed flux, turned into m^2/s
// with the time per step measured once at the reference u*, is within 5% of
// the law, for both laws and two cell sizes.
TEST(PhysicalUnits, FlatBedFluxFollowsTheLaw) {
  for (const char* law : {"LETTAU_1978", "KAWAMURA_1951"})
    for (const char* cell : {"1", "0.5"}) {
      const auto spec = test::spec_from(
          R"({"domain": {"nx": 64, "ny": 64, "cell_size_m": )" + std::string(cell) +
          R"(}, "layers": {"sand": {"constant": 2}}, "physics": {"flux_law": ")" + law +
          R"("}, "wind": {"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4}}})");
      const physics::Sand s = physics::sand_of(spec);
      const Calibration c = calibrate(spec);
      ASSERT_TRUE(c.physical);
      ASSERT_GT(c.dt_s, 0.0);
      for (double r : {1.1, 1.25, 1.5, 2.0, 2.5, 3.0}) {
        const double ustar = r * c.ustar_t;
        const FlatBedFlux f = measure_flat_bed_flux(spec, ustar, 0.0);
        const double sim = f.qx / c.dt_s, law_q = physics::flux_bulk(s, ustar);
        EXPECT_NEAR(sim / law_q, 1.0, 0.05)
            << law << " cells " << cell << " u*/u_t = " << r << ": simulated " << sim
            << " m^2/s, law " << law_q << " m^2/s";
        EXPECT_NEAR(f.qy, 0.0, 1e-12);
      }
    }
}

// Below the threshold nothing moves: the state after 40 steps is the initial
// one to the unit, in both transport modes, with relief on the bed (piles
// below the repose angle, where the venturi speed-up is largest).
TEST(PhysicalUnits, BelowThresholdNothingMoves) {
  for (const char* transport : {"EXPECTED", "STOCHASTIC"}) {
    const auto probe = test::spec_from(
        job_json(R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.1}})"));
    const double ut = physics::threshold(physics::sand_of(probe));
    const std::string wind = R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": )" +
                             std::to_string(0.9 * ut) + "}}";
    // Without the shear stress over relief (physics.shear_stress_a = 0):
    // only the venturi speeds up the crest.
    auto spec =
        test::spec_from(R"({"domain": {"nx": 64, "ny": 64, "cell_size_m": 1}, "transport": ")" +
                        std::string(transport) +
                        R"(", "physics": {"shear_stress_a": 0}, "layers": {"sand": {"constant": 0.5,
           "piles": [{"x_m": 32, "y_m": 32, "height": 3, "radius_m": 20}]}}, "wind": )" +
                        wind + "}");
    Simulation sim(spec, "", test::cpu_threads(1));
    const TileState before = sim.state();
    for (int k = 0; k < 40; ++k) sim.step();
    const TileState after = sim.state();
    EXPECT_EQ(test::owned(after.units[erg::fields::kSand]),
              test::owned(before.units[erg::fields::kSand]))
        << transport;
    for (auto a : test::owned(after.units[erg::fields::kAirborne])) ASSERT_EQ(a, 0) << transport;
    // With it (A = 3 of Kroy et al. 2002), the pile's u* rises by more than
    // the 11% that 0.9 u_t lacks towards the crest (Jackson & Hunt 1975), and
    // sand moves there, while the flat bed far from it stays.
    spec.mutable_physics()->set_shear_stress_a(3);
    Simulation sheared(spec, "", test::cpu_threads(1));
    for (int k = 0; k < 5; ++k) sheared.step();
    const auto sand0 = test::owned(before.units[erg::fields::kSand]);
    const auto sand1 = test::owned(sheared.state().units[erg::fields::kSand]);
    EXPECT_NE(sand1, sand0) << transport;
    for (int x = 0; x < 64; ++x)
      EXPECT_EQ(sand1[static_cast<size_t>(2) * 64 + x], sand0[2 * 64 + x]);
    // Just above the threshold, sand moves.
    const std::string above = R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": )" +
                              std::to_string(1.2 * ut) + "}}";
    auto spec2 = spec;
    spec2.mutable_wind()->mutable_constant()->set_speed_mps(1.2 * ut);
    Simulation sim2(spec2, "", test::cpu_threads(1));
    for (int k = 0; k < 5; ++k) sim2.step();
    EXPECT_NE(test::owned(sim2.state().units[erg::fields::kSand]),
              test::owned(before.units[erg::fields::kSand]))
        << transport;
  }
}

// The coarse window (wx x wy, `h` cells of halo) of the block means of a
// sinusoid h0 cos(k x) on fine cells, c fine cells to a coarse one, P coarse
// cells a period: the wind stage's window over such a relief.
std::vector<double> sinusoid_window(int P, int c, int h, int wx, int wy, double k, double h0) {
  std::vector<double> block(static_cast<size_t>(P), 0.0);
  for (int x = 0; x < c * P; ++x)
    block[static_cast<size_t>(x / c)] += h0 * std::cos(k * (x + 0.5)) / c;
  std::vector<double> window(static_cast<size_t>(wx) * wy);
  for (int j = 0; j < wy; ++j)
    for (int i = 0; i < wx; ++i)
      window[static_cast<size_t>(j) * wx + i] = block[static_cast<size_t>((i - h + P) % P)];
  return window;
}

// e . grad h (shear_stress::slope_at) over the window's inner cells.
std::vector<double> window_slope(const std::vector<double>& window, int wx, int wy, double ex,
                                 double ey, double delta_m) {
  std::vector<double> slope(window.size(), 0.0);
  for (int j = 1; j < wy - 1; ++j)
    for (int i = 1; i < wx - 1; ++i)
      slope[static_cast<size_t>(j) * wx + i] =
          shear_stress::slope_at(window.data(), wx, ex, ey, delta_m, i, j);
  return slope;
}

// A coarse stress row (cells -1 .. P) interpolated to the fine cells as the
// wind stage does, projected on cos(k x) and -sin(k x): the parts in phase
// with the relief and in quadrature with it.
std::pair<double, double> fine_cell_phases(const std::vector<float>& tau, int c, int P, double k) {
  double in_phase = 0, quadrature = 0;
  for (int x = 0; x < c * P; ++x) {
    const wind_warping::Axis ax = wind_warping::coarse_axis(x, c, 0);
    const double t = wind_warping::lerp_columns(tau[static_cast<size_t>(ax.i0)],
                                                tau[static_cast<size_t>(ax.i1)], ax);
    in_phase += 2.0 * t * std::cos(k * (x + 0.5)) / (c * P);
    quadrature -= 2.0 * t * std::sin(k * (x + 0.5)) / (c * P);
  }
  return {in_phase, quadrature};
}

// The shear stress over relief (stages/shear_stress.h) against its Fourier
// form tau1_hat / tau0 = A (k_x^2 / |k| + i B k_x) h_hat (Kroy, Sauermann &
// Herrmann 2002): over h = h0 sin(k e.x + phi), with e the wind's direction,
// tau1 / tau0 = A k h0 (sin phi + B cos phi). A 128 m wavelength on 4 m
// coarse cells, the wind at 30 degrees, the kernel truncated at 100 m: the
// truncated lattice sum is within 2% of A k h0 (central differences: (k
// delta)^2 / 6 = 0.6%, which the correction restores; the correction also
// undoes a block mean and an interpolation that this test does not apply,
// 1% at 128 m; the truncation of the 1 / r^2 tail the rest).
TEST(PhysicalUnits, ShearStressOverASinusoidFollowsKroyEtAl) {
  const double delta = 4, lambda = 128, k = 2 * kPi / lambda, h0 = 1.5;
  const double ex = std::cos(30 * kPi / 180), ey = std::sin(30 * kPi / 180);
  shear_stress::Params p;
  p.on = true;
  p.a = 3;
  p.b = 1;
  p.radius = shear_stress::kernel_radius(100, delta);
  ASSERT_EQ(p.radius, 25);
  shear_stress::Kernel kern;
  p.delta_m = delta;
  ASSERT_TRUE(kern.aim({static_cast<float>(ex), static_cast<float>(ey)}, p));
  const int h = p.radius + 2, n = 2 * h + 1;
  for (double phi : {0.0, 1.0, kPi / 2, 2.5}) {
    std::vector<double> window(static_cast<size_t>(n) * n);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        window[static_cast<size_t>(j) * n + i] =
            h0 * std::sin(k * (ex * (i - h) + ey * (j - h)) * delta + phi);
    const std::vector<double> slope = window_slope(window, n, n, kern.ex, kern.ey, delta);
    const float tau = shear_stress::perturbation_at(
        slope.data(), window.data(), n, kern.kernel_taps(), kern.correction_taps(), p, h, h);
    const double expect = p.a * k * h0 * (std::sin(phi) + p.b * std::cos(phi));
    EXPECT_NEAR(tau, expect, 0.02 * p.a * k * h0) << "phase " << phi;
  }
  // Flat ground: no perturbation, exactly.
  const Vec2 w{3.5f, -1.25f};
  EXPECT_EQ(shear_stress::surface_wind(0.0f, 0.0f, w).x, w.x);
  EXPECT_EQ(shear_stress::surface_wind(0.0f, 0.0f, w).y, w.y);
}

// The same on the fine cells, at the wavelengths of a dune's faces: a
// sinusoid h0 cos(k x) along x on 1 m cells, its exact 4 m block means (the
// coarse window), the stage's tau1 / tau0 at the coarse cells, interpolated
// back with the warping's bilinear weights, and its parts in phase and in
// quadrature with h against the theory's A h0 k cos^2(theta) (the K term)
// and A B h0 k cos(theta) (the B term), theta the wind's angle to x. The
// window alone gave 0.23-0.62 of the K term and 0.47-0.83 of the B term at
// 16-32 m (docs/physical-units.md); with the correction both are within 3%
// there and within 6% up to 128 m. Flat ground: exactly no perturbation.
TEST(PhysicalUnits, ShearStressOnTheFineCellsFollowsKroyEtAlAtDuneScales) {
  constexpr int c = 4, P = 96;  // coarse cells of 4 m, a 384 m period
  shear_stress::Params p;
  p.on = true;
  p.a = 3;
  p.b = 1;
  p.cx = p.cy = c;
  p.delta_m = c;
  p.radius = shear_stress::kernel_radius(100, p.delta_m);
  const int h = std::max(p.radius, shear_stress::kCorrectionRadius) + 2;
  const int wx = P + 2 * h, wy = 2 * h + 1;
  for (double theta : {0.0, 30.0}) {
    const double ex = std::cos(theta * kPi / 180), ey = std::sin(theta * kPi / 180);
    shear_stress::Kernel kern;
    ASSERT_TRUE(kern.aim({static_cast<float>(ex), static_cast<float>(ey)}, p));
    for (double lambda : {16.0, 24.0, 32.0, 48.0, 64.0, 128.0}) {
      const double k = 2 * kPi / lambda, h0 = 1.0;
      const std::vector<double> window = sinusoid_window(P, c, h, wx, wy, k, h0);
      const std::vector<double> slope = window_slope(window, wx, wy, kern.ex, kern.ey, p.delta_m);
      std::vector<float> tau(P + 2);  // coarse cells -1 .. P
      for (int i = 0; i < P + 2; ++i)
        tau[static_cast<size_t>(i)] =
            shear_stress::perturbation_at(slope.data(), window.data(), wx, kern.kernel_taps(),
                                          kern.correction_taps(), p, h - 1 + i, h);
      const auto [in_phase, quadrature] = fine_cell_phases(tau, c, P, k);
      const double kterm = in_phase / (p.a * h0 * k * ex * ex);
      const double bterm = quadrature / (p.a * p.b * h0 * k * ex);
      const double tol = lambda <= 32 ? 0.03 : 0.06;
      EXPECT_NEAR(kterm, 1.0, tol) << lambda << " m, wind at " << theta << " deg";
      EXPECT_NEAR(bterm, 1.0, tol) << lambda << " m, wind at " << theta << " deg";
    }
    std::vector<double> flat(static_cast<size_t>(wx) * wy, 7.25), zero(flat.size(), 0.0);
    EXPECT_EQ(shear_stress::perturbation_at(zero.data(), flat.data(), wx, kern.kernel_taps(),
                                            kern.correction_taps(), p, h, h),
              0.0f);
  }
}

// The component across the wind (Kroy, Sauermann & Herrmann 2002, sec. II):
// tau_y_hat / tau0 = A (k_x k_y / |k|) h_hat, k_y along the wind turned +90
// deg. On the fine cells as above, over h0 cos(k x) with the wind at theta
// to x, k_x = k cos(theta), k_y = -k sin(theta): tau_y / tau0 = -A h0 k
// cos(theta) sin(theta) cos(k x), nothing in quadrature. With the lateral
// correction the part in phase is within 3% of it at 16-32 m and 6% up to
// 128 m, the quadrature under 3% of A h0 k; the same over a sinusoid
// oblique to the grid (which a grid-aligned one does not test: the
// correction's sets xy and z). And a hill deflects the wind
// round it: over a Gaussian hill (4 m high, sigma 12 m) the stress across
// the wind points away from the hill's axis on its windward flanks and
// towards it in the lee, antisymmetric across the axis, 0 on it; and the
// surface wind turns with it (shear_stress::surface_wind).
TEST(PhysicalUnits, LateralShearStressFollowsKroyEtAlAndDeflectsTheWindRoundAHill) {
  constexpr int c = 4, P = 96;
  shear_stress::Params p;
  p.on = true;
  p.a = 4;
  p.b = 0.24f;
  p.cx = p.cy = c;
  p.delta_m = c;
  p.radius = shear_stress::kernel_radius(100, p.delta_m);
  const int h = std::max(p.radius, shear_stress::kCorrectionRadius) + 2;
  for (double theta : {30.0, 60.0}) {
    const double ex = std::cos(theta * kPi / 180), ey = std::sin(theta * kPi / 180);
    shear_stress::Kernel kern;
    ASSERT_TRUE(kern.aim({static_cast<float>(ex), static_cast<float>(ey)}, p));
    const int wx = P + 2 * h, wy = 2 * h + 1;
    for (double lambda : {16.0, 24.0, 32.0, 48.0, 64.0, 128.0}) {
      const double k = 2 * kPi / lambda, h0 = 1.0;
      const std::vector<double> window = sinusoid_window(P, c, h, wx, wy, k, h0);
      const std::vector<double> perp = window_slope(window, wx, wy, -kern.ey, kern.ex, p.delta_m);
      std::vector<float> tau(P + 2);
      for (int i = 0; i < P + 2; ++i)
        tau[static_cast<size_t>(i)] =
            shear_stress::lateral_at(perp.data(), window.data(), wx, kern.kernel_taps(),
                                     kern.lateral_taps(), p, h - 1 + i, h);
      const auto [in_phase, quadrature] = fine_cell_phases(tau, c, P, k);
      const double theory = -p.a * h0 * k * ex * ey;
      const double tol = lambda <= 32 ? 0.03 : 0.06;
      EXPECT_NEAR(in_phase / theory, 1.0, tol) << lambda << " m, wind at " << theta << " deg";
      EXPECT_LE(std::fabs(quadrature), 0.03 * p.a * h0 * k)
          << lambda << " m, wind at " << theta << " deg";
    }
  }
  // An oblique sinusoid h0 cos(k . x), k = kk (2, 1), its crests at 63
  // degrees to x (the parts of the correction that a sinusoid along a grid
  // axis or a diagonal does not see), on a torus of n x n fine cells, its
  // block means, tau_y on the coarse cells, interpolated back in both
  // directions: against A h0 k_x k_y / |k| for the wind along x and at -30
  // and 30 degrees.
  for (double theta : {0.0, -30.0, 30.0}) {
    const double ex = std::cos(theta * kPi / 180), ey = std::sin(theta * kPi / 180);
    shear_stress::Kernel kern;
    ASSERT_TRUE(kern.aim({static_cast<float>(ex), static_cast<float>(ey)}, p));
    for (int nc : {12, 16, 32, 64}) {  // 21.5, 28.6, 57.2, 114.5 m across the crests
      const int nf = c * nc, w = nc + 2 * h;
      const double kk = 2 * kPi / nf;  // along x and along y
      std::vector<double> block(static_cast<size_t>(nc) * nc, 0.0);
      for (int y = 0; y < nf; ++y)
        for (int x = 0; x < nf; ++x)
          block[static_cast<size_t>(y / c) * nc + x / c] +=
              std::cos(2 * kk * (x + 0.5) + kk * (y + 0.5)) / (c * c);
      std::vector<double> window(static_cast<size_t>(w) * w), perp(window.size(), 0.0);
      for (int j = 0; j < w; ++j)
        for (int i = 0; i < w; ++i)
          window[static_cast<size_t>(j) * w + i] =
              block[static_cast<size_t>((j - h + 4 * nc) % nc) * nc + (i - h + 4 * nc) % nc];
      for (int j = 1; j < w - 1; ++j)
        for (int i = 1; i < w - 1; ++i)
          perp[static_cast<size_t>(j) * w + i] =
              shear_stress::slope_at(window.data(), w, -kern.ey, kern.ex, p.delta_m, i, j);
      const int g = nc + 2;  // coarse cells -1 .. nc
      std::vector<float> tau(static_cast<size_t>(g) * g);
      for (int j = 0; j < g; ++j)
        for (int i = 0; i < g; ++i)
          tau[static_cast<size_t>(j) * g + i] =
              shear_stress::lateral_at(perp.data(), window.data(), w, kern.kernel_taps(),
                                       kern.lateral_taps(), p, h - 1 + i, h - 1 + j);
      double in_phase = 0, quadrature = 0;
      for (int y = 0; y < nf; ++y)
        for (int x = 0; x < nf; ++x) {
          const double t =
              wind_warping::sample_at(tau.data(), g, wind_warping::coarse_axis(x, c, 0),
                                      wind_warping::coarse_axis(y, c, 0));
          const double ph = 2 * kk * (x + 0.5) + kk * (y + 0.5);
          in_phase += 2.0 * t * std::cos(ph) / (nf * nf);
          quadrature -= 2.0 * t * std::sin(ph) / (nf * nf);
        }
      // k_x = kk (2 ex + ey), k_y = kk (ex - 2 ey) in the wind's frame; |k| = kk sqrt(5).
      const double theory = p.a * kk * (2 * ex + ey) * (ex - 2 * ey) / std::sqrt(5.0);
      const double lambda = nf / std::sqrt(5.0);
      // Within 2% of A |k| h0 at every angle; within 3% (6% above 32 m) of
      // the theory's own value where that is not small (at 30 degrees k is
      // within 8 degrees of the wind: tau_y is 0.06 A |k| h0).
      EXPECT_NEAR(in_phase, theory, 0.02 * p.a * kk * std::sqrt(5.0))
          << lambda << " m across the crests, wind at " << theta << " deg";
      if (theta <= 0.0) {
        EXPECT_NEAR(in_phase / theory, 1.0, lambda <= 32 ? 0.03 : 0.06)
            << lambda << " m across the crests, wind at " << theta << " deg";
      }
      EXPECT_LE(std::fabs(quadrature), 0.03 * p.a * kk * std::sqrt(5.0));
    }
  }
  // A Gaussian hill on coarse cells of 4 m, the wind along x.
  shear_stress::Kernel kern;
  ASSERT_TRUE(kern.aim({1.0f, 0.0f}, p));
  const int m = h + 6, n = 2 * m + 1;  // the window reaches 6 coarse cells from the top
  std::vector<double> hill(static_cast<size_t>(n) * n), perp(hill.size(), 0.0);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = (i - m) * p.delta_m, y = (j - m) * p.delta_m;
      hill[static_cast<size_t>(j) * n + i] = 4.0 * std::exp(-(x * x + y * y) / (2 * 12.0 * 12.0));
    }
  for (int j = 1; j < n - 1; ++j)
    for (int i = 1; i < n - 1; ++i)
      perp[static_cast<size_t>(j) * n + i] =
          shear_stress::slope_at(hill.data(), n, 0.0, 1.0, p.delta_m, i, j);
  auto tau_y = [&](int du, int dv) {  // at (du, dv) coarse cells from the top
    return shear_stress::lateral_at(perp.data(), hill.data(), n, kern.kernel_taps(),
                                    kern.lateral_taps(), p, m + du, m + dv);
  };
  for (int d : {2, 3, 4}) {
    EXPECT_GT(tau_y(-d, d), 0.02f) << "windward, left of the axis";
    EXPECT_LT(tau_y(-d, -d), -0.02f) << "windward, right of the axis";
    EXPECT_LT(tau_y(d, d), -0.02f) << "lee, left of the axis";
    EXPECT_NEAR(tau_y(-d, d), -tau_y(-d, -d), 1e-6);
  }
  EXPECT_NEAR(tau_y(-3, 0), 0.0f, 1e-6);
  // The surface wind turns away from the axis there and keeps its speed's
  // law: flat ground gives the wind back; tau_y alone turns it by atan(tau_y).
  const Vec2 w0{5.0f, 0.0f};
  const Vec2 flat = shear_stress::surface_wind(0.0f, 0.0f, w0);
  EXPECT_FLOAT_EQ(flat.x, 5.0f);
  EXPECT_EQ(flat.y, 0.0f);
  const Vec2 turned = shear_stress::surface_wind(0.0f, tau_y(-3, 3), w0);
  EXPECT_GT(turned.y, 0.0f);
  EXPECT_NEAR(std::atan2(turned.y, turned.x), std::atan(tau_y(-3, 3)), 1e-6);
  EXPECT_NEAR(std::hypot(turned.x, turned.y),
              5.0 * std::pow(1.0 + tau_y(-3, 3) * tau_y(-3, 3), 0.25), 1e-5);
}

// The hop of the physical modes is deposit_on_sand x the saturation length
// 2.2 (rho_s / rho) d of Andreotti, Claudin & Pouliquen 2010 (1.19 m for
// the default sand), at least one cell, at most model.max_hop_m.
TEST(PhysicalUnits, HopIsTheSaturationLengthResolvedOnTheGrid) {
  auto hop = [](const std::string& cell, const std::string& physics) {
    const auto spec = test::spec_from(R"({"domain": {"nx": 64, "ny": 64, "cell_size_m": )" + cell +
                                      R"(}, "layers": {"sand": {"constant": 2}}, "physics": {)" +
                                      physics + R"(}, "wind": {"speed_is": "SHEAR_VELOCITY",
                                      "constant": {"speed_mps": 0.4}}})");
    return make_model(spec, 64, 64, 0, 0).saltation.max_hop_m;
  };
  const double lsat = 2.2 * 2650 / 1.225 * 0.00025;
  EXPECT_NEAR(hop("0.5", ""), 0.6 * lsat, 1e-5);
  EXPECT_FLOAT_EQ(hop("1", ""), 1.0f);                              // one cell
  EXPECT_FLOAT_EQ(hop("1", R"("saturation_length_m": 5)"), 3.0f);   // 0.6 x 5 m
  EXPECT_FLOAT_EQ(hop("1", R"("saturation_length_m": 50)"), 8.0f);  // max_hop_m
  // Model units keep [P19]'s hop.
  const auto model = test::spec_from(job_json(R"({"constant": {"speed_mps": 5}})"));
  EXPECT_FLOAT_EQ(make_model(model, 64, 64, 0, 0).saltation.max_hop_m, 8.0f);
}

// The hop's deflection down the slope (physics.hop_slope_deflection,
// stages/saltation.h): across the wind a slope s turns the hop by
// atan(k s) towards downslope, keeping its length; along the wind it leaves
// the direction alone; k = 0 is the undeflected landing to the bit. The
// slope is the ground's, an obstacle next to the cell counting as level.
TEST(PhysicalUnits, HopTurnsDownTheSlopeAcrossTheWind) {
  saltation::Params p{};
  p.cell_m = 1.0f;
  p.max_hop_m = 4.0f;
  p.ustar_per_mps = 1.0f;  // physical: the hop is max_hop_m
  p.slope_k = 0.34f;
  const Vec2 w{0.45f, 0.0f};
  const auto at = [](const saltation::Landing& L) {
    return std::pair<double, double>{L.x0 + L.fx - 10.0, L.y0 + L.fy - 20.0};
  };
  // Ground rising towards +y by 0.5 m per metre: the hop turns towards -y.
  const auto [ax, ay] = at(saltation::deflected_landing(10, 20, w, {0.0f, 0.5f}, p));
  const double theta = std::atan(0.34 * 0.5);
  EXPECT_NEAR(ax, 4.0 * std::cos(theta), 1e-5);
  EXPECT_NEAR(ay, -4.0 * std::sin(theta), 1e-5);
  // A slope along the wind: the same direction, the same length.
  const auto [bx, by] = at(saltation::deflected_landing(10, 20, w, {0.5f, 0.0f}, p));
  EXPECT_NEAR(bx, 4.0, 1e-5);
  EXPECT_NEAR(by, 0.0, 1e-6);

  // The ground's slope: a ramp of 0.5 per cell along y, by central
  // differences; an obstacle to the north counts as level with the cell.
  constexpr long kPitch = 5;
  std::vector<float> h(25), o(25, 0.0f);
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 5; ++x) h[static_cast<size_t>(y * kPitch + x)] = 0.5f * y + 0.25f * x;
  const float* hc = h.data() + 2 * kPitch + 2;
  const float* oc = o.data() + 2 * kPitch + 2;
  const Vec2 ramp = saltation::ground_slope(hc, oc, kPitch, 0.5f);
  EXPECT_FLOAT_EQ(ramp.x, 0.5f);  // 0.25 per cell of 0.5 m
  EXPECT_FLOAT_EQ(ramp.y, 1.0f);

  // The scatters' landing over that ground: deflected down its slope when
  // k > 0; off, the bits of the landing without a slope.
  p.cell_m = 0.5f;
  const Vec2 v{0.3f, 0.2f};
  const saltation::Landing over = saltation::landing_over(10, 20, v, hc, oc, kPitch, p);
  const saltation::Landing down = saltation::deflected_landing(10, 20, v, ramp, p);
  const saltation::Landing plain = saltation::landing(10, 20, v, p);
  EXPECT_EQ(std::tie(over.x0, over.y0, over.fx, over.fy),
            std::tie(down.x0, down.y0, down.fx, down.fy));
  EXPECT_NE(std::tie(over.x0, over.y0, over.fx, over.fy),
            std::tie(plain.x0, plain.y0, plain.fx, plain.fy));
  p.slope_k = 0.0f;
  const saltation::Landing off = saltation::landing_over(10, 20, v, hc, oc, kPitch, p);
  EXPECT_EQ(std::tie(off.x0, off.y0, off.fx, off.fy),
            std::tie(plain.x0, plain.y0, plain.fx, plain.fy));

  o[3 * kPitch + 2] = 2.0f;
  const Vec2 walled = saltation::ground_slope(hc, oc, kPitch, 0.5f);
  EXPECT_FLOAT_EQ(walled.x, 0.5f);
  EXPECT_FLOAT_EQ(walled.y, 0.5f);  // (centre - south) / 2 cells
}

// The deflection in a run: a sand cone on bedrock under u* = 0.4 m/s spreads
// further across the wind with k = 0.34 than without (the flanks' hops turn
// outwards: 7.5 m against 6.2 m when measured), with the same sand.
TEST(PhysicalUnits, DeflectedHopsSpreadAPileAcrossTheWind) {
  const auto lateral_spread = [](const std::string& k) {
    const auto spec = test::spec_from(R"({"domain": {"nx": 96, "ny": 64, "cell_size_m": 1},
      "layers": {"sand": {"piles": [{"x_m": 40, "y_m": 32, "height": 4, "radius_m": 14}]}},
      "wind": {"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4}},
      "physics": {"hop_slope_deflection": )" +
                                      k + R"(}, "run": {"steps": 300}})");
    Simulation sim(spec, ".", test::cpu_threads(2));
    const Totals t0 = sim.totals();
    for (int i = 0; i < 300; ++i) sim.step();
    EXPECT_EQ(to_decimal(sim.totals().all_sand()), to_decimal(t0.all_sand())) << "k " << k;
    const std::vector<double> sand = test::sand_m(sim.state());
    double m = 0, my = 0, myy = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 96; ++x) {
        const double s = sand[static_cast<size_t>(y) * 96 + x];
        m += s;
        my += s * y;
        myy += s * y * y;
      }
    return std::sqrt(myy / m - (my / m) * (my / m));
  };
  const double off = lateral_spread("0"), on = lateral_spread("0.34");
  EXPECT_GT(on, off * 1.1) << "lateral spread " << on << " m with the deflection, " << off
                           << " m without";
}

// A wind rose of four directions: the drift simulated over 20000 draws of
// the rose (each step's wind from the regime, its flux measured over flat
// sand and converted with the calibrated time per step) against Fryberger &
// Dean 1979: DP = sum of p_k q(u*_k), RDP = |sum p_k q(u*_k) e_k|, RDD its
// direction, q the same flux law.
TEST(PhysicalUnits, WindRoseDriftMatchesDpRdpRdd) {
  const auto probe = test::spec_from(
      job_json(R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4}})"));
  const double ut = physics::threshold(physics::sand_of(probe));
  struct E {
    double dir, r, p;
  };
  const E rose[] = {{0, 1.6, 0.4}, {75, 2.2, 0.2}, {200, 1.3, 0.3}, {305, 2.7, 0.1}};
  std::string entries;
  for (const E& e : rose) {
    // (Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "," + string.)
    if (!entries.empty()) entries.append(",");
    entries.append("{\"direction_deg\": ").append(std::to_string(e.dir));
    entries.append(", \"speed_mps\": ").append(std::to_string(e.r * ut));
    entries.append(", \"probability\": ").append(std::to_string(e.p)).append("}");
  }
  const auto spec = test::spec_from(
      job_json(R"({"speed_is": "SHEAR_VELOCITY", "rose": {"entries": [)" + entries + "]}}"));
  const physics::Sand s = physics::sand_of(spec);
  const Calibration c = calibrate(spec);

  const Drift d = wind_drift(spec, c, 20000);
  ASSERT_EQ(d.winds, 4);
  // The law's numbers by hand, from the rose's probabilities.
  double dp = 0, rx = 0, ry = 0;
  for (const E& e : rose) {
    const double q = physics::flux_bulk(s, e.r * ut);
    dp += e.p * q;
    rx += e.p * q * std::cos(e.dir * kPi / 180);
    ry += e.p * q * std::sin(e.dir * kPi / 180);
  }
  const double rdp = std::hypot(rx, ry), rdd = std::atan2(ry, rx) * 180 / kPi;
  EXPECT_NEAR(d.law_dp / dp, 1.0, 1e-5);
  EXPECT_NEAR(d.law_rdp / rdp, 1.0, 1e-5);
  const double sdp = d.sim_dp, srdp = d.sim_rdp, srdd = d.sim_rdd_deg;
  EXPECT_NEAR(sdp / dp, 1.0, 0.05) << "DP simulated " << sdp << ", Fryberger " << dp;
  EXPECT_NEAR(srdp / rdp, 1.0, 0.05) << "RDP simulated " << srdp << ", Fryberger " << rdp;
  double dd = std::fmod(srdd - rdd + 540.0, 360.0) - 180.0;
  EXPECT_LE(std::fabs(dd), 3.0) << "RDD simulated " << srdd << ", Fryberger " << rdd;
  // RDP / DP: a measure of the directional variability (Fryberger 1979).
  EXPECT_NEAR(srdp / sdp, rdp / dp, 0.05 * rdp / dp);
}

// The time per step is a measurement: it changes with the model parameters
// that change the model's flux (the lift) and not with the wind of the job.
TEST(PhysicalUnits, TimePerStepIsMeasured) {
  const auto a = test::spec_from(
      job_json(R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4}})"));
  const auto b = test::spec_from(
      job_json(R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.6}})"));
  const auto half =
      test::spec_from(job_json(R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4}})",
                               R"(, "model": {"slab_m": 0.05})"));
  const Calibration ca = calibrate(a), cb = calibrate(b), ch = calibrate(half);
  EXPECT_EQ(ca.dt_s, cb.dt_s);
  EXPECT_NEAR(ch.dt_s / ca.dt_s, 0.5, 0.01);
  // Model units: the label.
  const auto legacy = test::spec_from(job_json(R"({"constant": {"speed_mps": 5}})"));
  const Calibration cl = calibrate(legacy);
  EXPECT_FALSE(cl.physical);
  EXPECT_EQ(cl.dt_s, 10 * 86400.0);
}

// Snapshots carry the time in seconds, the wind of the step and the
// calibration (detail::write_physical_attrs).
TEST(PhysicalUnits, SnapshotsCarryTimeWindAndCalibration) {
  const auto spec = test::spec_from(job_json(
      R"({"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.4, "direction_deg": 30}})"));
  Simulation sim(spec, "", test::cpu_threads(1));
  for (int k = 0; k < 3; ++k) sim.step();
  const io::SnapshotMeta m = sim.snapshot_meta();
  const Calibration c = calibrate(spec);
  EXPECT_TRUE(m.physical);
  EXPECT_EQ(m.dt_s, c.dt_s);
  EXPECT_DOUBLE_EQ(m.time_s, 3 * c.dt_s);
  EXPECT_DOUBLE_EQ(m.time_days, 3 * c.dt_s / 86400);
  EXPECT_NEAR(m.shear_velocity_mps, 0.4, 1e-6);
  EXPECT_NEAR(m.wind_direction_deg, 30, 1e-4);
  EXPECT_EQ(m.threshold_mps, c.ustar_t);
  EXPECT_EQ(m.calibration_flux_m2_per_step, c.q_model_m2_step);
  EXPECT_NE(m.flux_law.find("Lettau"), std::string::npos);
  const std::string path = ::testing::TempDir() + "/physical_units_snapshot.h5";
  const Simulation::Output o = sim.output();
  io::SnapshotFields f;
  f[erg::fields::kBedrock].data = o[erg::fields::kBedrock].data();
  f[erg::fields::kSand].data = o[erg::fields::kSand].data();
  f[erg::fields::kVegetation].data = o[erg::fields::kVegetation].data();
  f[erg::fields::kWindX].data = o[erg::fields::kWindX].data();
  f[erg::fields::kWindY].data = o[erg::fields::kWindY].data();
  io::write_snapshot(path, m, f);
  const io::Snapshot back = io::read_snapshot(path, true);
  EXPECT_DOUBLE_EQ(back.meta.time_s, 3 * c.dt_s);
}

}  // namespace
}  // namespace erg
