// SPDX-License-Identifier: Apache-2.0
// Amplification [P19 6] measured on small synthetic snapshots: the ripples
// of the Nishimori-Ouchi model [ON00 2(1)] lie perpendicular to the wind
// (2-D DFT of the amplified field minus the upsampled base), their wavelength
// grows with the wind speed, their lee is steeper than their stoss under one
// wind (the reptation splash of Anderson 1987) and they are near-symmetric
// under alternating winds, they vanish in wind shadow; bumps
// grow around plants (and obstacles when the snapshot has them).
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <vector>

#include "../common/temp_dir.h"
#include "amplify/amplify.h"
#include "io/io.h"
#include "job/spec.h"
#include "wind/regime.h"

namespace {

using erg::Vec2;
using namespace erg::amplify;

constexpr double kPi = std::numbers::pi;

AmplifyParams defaults() {
  erg::v1::JobSpec spec;
  erg::job::apply_defaults(spec);
  return spec.amplify();
}

// A flat metre of sand under a uniform wind, no shadow, no plants.
AmplifyInput flat_sand(int n, double speed, double dir_deg) {
  AmplifyInput in;
  in.nx = in.ny = n;
  in.cell_size_m = 1;
  const size_t cells = static_cast<size_t>(n) * n;
  in.bedrock.assign(cells, 0.0f);
  in.sand.assign(cells, 1.0f);
  in.vegetation.assign(cells, 0.0f);
  in.shadow.assign(cells, 0.0f);
  in.wind.resize(2 * cells);
  const Vec2 w = erg::wind::direction(dir_deg);
  for (size_t c = 0; c < cells; ++c) {
    in.wind[2 * c] = static_cast<float>(speed) * w.x;
    in.wind[2 * c + 1] = static_cast<float>(speed) * w.y;
  }
  const Vec2 a = {static_cast<float>(speed) * w.x, static_cast<float>(speed) * w.y};
  in.wind_history.assign(100, a);
  in.seed = 11;
  return in;
}

// What amplification added: amplified height minus the upsampled base.
std::vector<double> detail_of(const AmplifiedLayers& a) {
  std::vector<double> d(a.height.size());
  for (size_t c = 0; c < d.size(); ++c) d[c] = static_cast<double>(a.height[c]) - a.base[c];
  return d;
}

struct Spectrum {
  double wave_angle_deg = 0;  // direction of the dominant wave vector, [0, 180)
  double peak_angle_deg = 0;  // of the single strongest bin
  double wavelength_cells = 0;
};

// 2-D DFT (separable, naive: the grids are small) of a periodic n x n field;
// the power-weighted mean orientation of the wave vectors (doubled angles, so
// k and -k agree) and wavelength, over the bins holding > 10 % of the peak.
Spectrum spectrum(const std::vector<double>& f, int n) {
  std::vector<std::complex<double>> tw(n), a(static_cast<size_t>(n) * n), b(a.size());
  for (int k = 0; k < n; ++k) tw[k] = std::polar(1.0, -2 * kPi * k / n);
  double mean = 0;
  for (double v : f) mean += v;
  mean /= static_cast<double>(f.size());
  for (int j = 0; j < n; ++j)
    for (int kx = 0; kx < n; ++kx) {
      std::complex<double> s = 0;
      for (int i = 0; i < n; ++i)
        s += (f[static_cast<size_t>(j) * n + i] - mean) * tw[(kx * i) % n];
      a[static_cast<size_t>(j) * n + kx] = s;
    }
  for (int kx = 0; kx < n; ++kx)
    for (int ky = 0; ky < n; ++ky) {
      std::complex<double> s = 0;
      for (int j = 0; j < n; ++j) s += a[static_cast<size_t>(j) * n + kx] * tw[(ky * j) % n];
      b[static_cast<size_t>(ky) * n + kx] = s;
    }
  auto freq = [n](int k) { return k <= n / 2 ? k : k - n; };
  double peak = 0;
  int pkx = 0, pky = 0;
  for (int ky = 0; ky < n; ++ky)
    for (int kx = 0; kx < n; ++kx) {
      if (kx == 0 && ky == 0) continue;
      const double p = std::norm(b[static_cast<size_t>(ky) * n + kx]);
      if (p > peak) peak = p, pkx = freq(kx), pky = freq(ky);
    }
  double sc = 0, ss = 0, sk = 0, sw = 0;
  for (int ky = 0; ky < n; ++ky)
    for (int kx = 0; kx < n; ++kx) {
      if (kx == 0 && ky == 0) continue;
      const double p = std::norm(b[static_cast<size_t>(ky) * n + kx]);
      if (p < 0.1 * peak) continue;
      const double fx = freq(kx), fy = freq(ky);
      const double phi = std::atan2(fy, fx);
      sc += p * std::cos(2 * phi);
      ss += p * std::sin(2 * phi);
      sk += p * std::hypot(fx, fy);
      sw += p;
    }
  Spectrum s;
  s.wave_angle_deg = std::fmod(0.5 * std::atan2(ss, sc) * 180 / kPi + 180, 180.0);
  s.peak_angle_deg = std::fmod(std::atan2(pky, pkx) * 180 / kPi + 360, 180.0);
  s.wavelength_cells = n / (sk / sw);
  return s;
}

// Difference of two axes in degrees, modulo 180 (an axis has no sign).
double axis_difference(double a, double b) {
  const double d = std::fmod(std::fabs(a - b), 180.0);
  return std::min(d, 180 - d);
}

// Skewness of the slope along +x and the ratio of the mean rising slope to
// the mean falling one: 0 and 1 for a symmetric profile.
struct Asymmetry {
  double skewness = 0, slope_ratio = 1;
};
Asymmetry asymmetry_along_x(const std::vector<double>& f, int n) {
  std::vector<double> g;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      g.push_back(0.5 * (f[static_cast<size_t>(j) * n + (i + 1) % n] -
                         f[static_cast<size_t>(j) * n + (i + n - 1) % n]));
  double m = 0;
  for (double v : g) m += v;
  m /= static_cast<double>(g.size());
  double m2 = 0, m3 = 0, up = 0, down = 0;
  int nu = 0, nd = 0;
  for (double v : g) {
    m2 += (v - m) * (v - m);
    m3 += (v - m) * (v - m) * (v - m);
    if (v > 0) up += v, ++nu;
    if (v < 0) down -= v, ++nd;
  }
  m2 /= static_cast<double>(g.size());
  m3 /= static_cast<double>(g.size());
  return {m3 / std::pow(m2, 1.5), (up / nu) / (down / nd)};
}

double rms(const std::vector<double>& f) {
  double s = 0;
  for (double v : f) s += v * v;
  return std::sqrt(s / static_cast<double>(f.size()));
}

constexpr int kCoarse = 16;  // 16 x 16 cells of 1 m
constexpr int kUp = 8;       // 128 x 128 fine cells of 12.5 cm
const Region kAll{0, 0, kCoarse, kCoarse};

TEST(Ripples, PerpendicularToTheWind) {
  const AmplifyParams p = defaults();
  for (double dir : {0.0, 35.0, 90.0}) {
    const AmplifiedLayers a = amplify_layers(flat_sand(kCoarse, 5, dir), kAll, kUp, p);
    const Spectrum s = spectrum(detail_of(a), a.nx);
    std::printf(
        "wind %5.1f deg: wave vector %6.1f deg (peak bin %6.1f), crests %6.1f deg, "
        "wavelength %.2f cells\n",
        dir, s.wave_angle_deg, s.peak_angle_deg, std::fmod(s.wave_angle_deg + 90, 180.0),
        s.wavelength_cells);
    // The wave vector is along the wind, so the crests are perpendicular to it.
    EXPECT_LT(axis_difference(s.wave_angle_deg, dir), 10.0) << "wind " << dir;
    EXPECT_GT(rms(detail_of(a)), 0.5 * p.ripple_height_m());
  }
}

TEST(Ripples, WavelengthGrowsWithWindSpeed) {
  const AmplifyParams p = defaults();
  double previous = 0;
  for (double speed : {4.0, 6.0, 9.0}) {
    const AmplifiedLayers a = amplify_layers(flat_sand(kCoarse, speed, 0), kAll, kUp, p);
    const Spectrum s = spectrum(detail_of(a), a.nx);
    std::printf("wind %.1f m/s: L0 = %.2f cells, wavelength %.2f cells (%.3f m)\n", speed,
                speed * p.ripple_hop_cells_per_mps(), s.wavelength_cells,
                s.wavelength_cells * a.cell_size_m);
    EXPECT_GT(s.wavelength_cells, 1.15 * previous) << "at " << speed << " m/s";
    previous = s.wavelength_cells;
  }
}

// Real wind ripples have a gentle stoss and a steep lee under one wind [A87]
// (slopes along +x, the wind: a negative skewness, rising slopes gentler than
// falling ones), and are near-symmetric when the wind reverses often.
TEST(Ripples, SteepLeeUnderOneWindSymmetricUnderAlternatingWinds) {
  const AmplifyParams p = defaults();
  AmplifyInput one = flat_sand(kCoarse, 9, 0);
  AmplifyInput alternating = one;
  for (size_t s = 0; s < alternating.wind_history.size(); ++s)
    if ((s / 20) % 2 == 1) alternating.wind_history[s] = {-9, 0};  // period 20 steps, 180 deg
  const Asymmetry a1 =
      asymmetry_along_x(detail_of(amplify_layers(one, kAll, kUp, p)), kCoarse * kUp);
  const Asymmetry a2 =
      asymmetry_along_x(detail_of(amplify_layers(alternating, kAll, kUp, p)), kCoarse * kUp);
  std::printf("one wind: slope skewness %.3f, stoss/lee slope %.3f\n", a1.skewness, a1.slope_ratio);
  std::printf("alternating: slope skewness %.3f, stoss/lee slope %.3f\n", a2.skewness,
              a2.slope_ratio);
  EXPECT_LT(a1.skewness, -0.2) << "the lee should be the steep face";
  EXPECT_LT(a1.slope_ratio, 0.85) << "mean stoss slope over mean lee slope";
  EXPECT_LT(std::fabs(a2.skewness), 0.4 * std::fabs(a1.skewness));
  EXPECT_GT(std::fabs(std::log(a1.slope_ratio)), 2 * std::fabs(std::log(a2.slope_ratio)));
}

// Without the reptation splash the lattice model alone makes the stoss the
// steep face: the splash [A87] is what turns it.
TEST(Ripples, ReptationSplashMakesTheLeeSteep) {
  AmplifyParams p = defaults();
  p.set_ripple_reptation(0);
  const Asymmetry a0 = asymmetry_along_x(
      detail_of(amplify_layers(flat_sand(kCoarse, 9, 0), kAll, kUp, p)), kCoarse * kUp);
  std::printf("no reptation: slope skewness %.3f, stoss/lee slope %.3f\n", a0.skewness,
              a0.slope_ratio);
  EXPECT_GT(a0.skewness, 0.1);
}

TEST(Ripples, SuppressedInWindShadow) {
  const AmplifyParams p = defaults();
  AmplifyInput in = flat_sand(kCoarse, 5, 0);
  for (int j = 0; j < kCoarse; ++j)
    for (int i = 0; i < kCoarse / 2; ++i) in.shadow[static_cast<size_t>(j) * kCoarse + i] = 1;
  const AmplifiedLayers a = amplify_layers(in, kAll, kUp, p);
  const std::vector<double> d = detail_of(a);
  // Away (2 cells) from the edges of the shadowed half.
  std::vector<double> shadowed, open;
  for (int j = 0; j < a.ny; ++j)
    for (int i = 0; i < a.nx; ++i) {
      const int ci = i / kUp;
      if (ci >= 2 && ci < kCoarse / 2 - 2) shadowed.push_back(d[static_cast<size_t>(j) * a.nx + i]);
      if (ci >= kCoarse / 2 + 2 && ci < kCoarse - 2)
        open.push_back(d[static_cast<size_t>(j) * a.nx + i]);
    }
  std::printf("ripple rms: shadowed %.5f m, open %.5f m\n", rms(shadowed), rms(open));
  // Ripples grow on the open half (drained into the shadow, less than on
  // open sand everywhere) and not at all in the shadow.
  EXPECT_GT(rms(open), 0.3 * p.ripple_height_m());
  EXPECT_LT(rms(shadowed), 0.05 * rms(open));
}

TEST(Ripples, DeterministicSeededAndPeriodic) {
  const AmplifyParams p = defaults();
  const AmplifyInput in = flat_sand(kCoarse, 5, 35);
  const std::vector<float> h1 = amplify(in, kAll, kUp, p), h2 = amplify(in, kAll, kUp, p);
  EXPECT_EQ(h1, h2);
  AmplifyInput other = in;
  other.seed = 12;
  EXPECT_NE(h1, amplify(other, kAll, kUp, p));
  // On a region spanning the torus the field wraps: steps across the seam
  // are no larger than steps inside.
  const int n = kCoarse * kUp;
  double seam = 0, inside = 0;
  for (int j = 0; j < n; ++j) {
    seam += std::fabs(h1[static_cast<size_t>(j) * n] - h1[static_cast<size_t>(j) * n + n - 1]);
    inside += std::fabs(h1[static_cast<size_t>(j) * n + n / 2] -
                        h1[static_cast<size_t>(j) * n + n / 2 - 1]);
  }
  EXPECT_LT(seam, 2 * inside);
}

// Large grids run creep rows in parallel: the same bits on 1 and 2 threads.
TEST(Ripples, SameBitsOnAnyThreadCount) {
  AmplifyParams p = defaults();
  p.set_ripple_iterations(12);
  const AmplifyInput in = flat_sand(64, 6, 35);  // 512 x 512 fine cells
  omp_set_num_threads(1);
  const std::vector<float> one = amplify(in, Region{0, 0, 64, 64}, 8, p);
  omp_set_num_threads(2);
  const std::vector<float> two = amplify(in, Region{0, 0, 64, 64}, 8, p);
  EXPECT_EQ(one, two);
}

TEST(Amplify, RegionMayWrapAndBadArgumentsAreNamed) {
  const AmplifyParams p = defaults();
  AmplifyInput in = flat_sand(kCoarse, 5, 0);
  for (int j = 0; j < kCoarse; ++j)
    for (int i = 0; i < kCoarse; ++i)
      in.bedrock[static_cast<size_t>(j) * kCoarse + i] = static_cast<float>(i);
  const AmplifiedLayers a = amplify_layers(in, Region{12, 4, 8, 4}, 4, p);
  EXPECT_EQ(a.nx, 32);
  EXPECT_EQ(a.ny, 16);
  EXPECT_DOUBLE_EQ(a.cell_size_m, 0.25);
  // Fine cell 2 of cell 12 sits at x = 12.625 (between centres 12.5 and
  // 13.5); the bicubic of a linear ramp is the ramp.
  EXPECT_NEAR(a.base[2], 12.125 + 1, 1e-5);
  // Cell 16 is cell 0 of the torus: the same terrain as a region at x0 = 0.
  const AmplifiedLayers b = amplify_layers(in, Region{0, 4, 8, 4}, 4, p);
  for (int j = 0; j < 16; ++j)
    for (int i = 0; i < 16; ++i)
      EXPECT_EQ(a.base[static_cast<size_t>(j) * 32 + 16 + i],
                b.base[static_cast<size_t>(j) * 32 + i]);
  EXPECT_THROW(amplify(in, Region{0, 0, 17, 4}, 4, p), std::invalid_argument);
  EXPECT_THROW(amplify(in, Region{0, 0, 4, 4}, 0, p), std::invalid_argument);
  try {
    parse_region("3,4,100,2", kCoarse, kCoarse);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("W = 100 is out of range; allowed [1, 16]"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(parse_region("3,4,x", kCoarse, kCoarse), std::invalid_argument);
  const Region r = parse_region("3,4,5,6", kCoarse, kCoarse);
  EXPECT_EQ(r.x0 + r.y0 + r.w + r.h, 18);
}

TEST(Bumps, AroundPlantsProportionalToDensity) {
  AmplifyParams p = defaults();
  p.set_ripple_height_m(0);  // bumps alone
  p.set_bump_plants_per_cell(4);
  AmplifyInput in = flat_sand(32, 5, 0);
  auto disk = [&](int cx, int cy, float v) {
    for (int j = cy - 2; j <= cy + 2; ++j)
      for (int i = cx - 2; i <= cx + 2; ++i) in.vegetation[static_cast<size_t>(j) * 32 + i] = v;
  };
  disk(8, 16, 0.9f);
  disk(24, 16, 0.3f);
  const AmplifiedLayers a = amplify_layers(in, Region{0, 0, 32, 32}, 4, p);
  auto max_in = [&](int x0, int x1, int y0, int y1) {
    double m = 0;
    for (int j = y0 * 4; j < y1 * 4; ++j)
      for (int i = x0 * 4; i < x1 * 4; ++i)
        m = std::max(m, static_cast<double>(a.bumps[static_cast<size_t>(j) * a.nx + i]));
    return m;
  };
  const double dense = max_in(4, 14, 12, 21), sparse = max_in(20, 30, 12, 21);
  const double far = max_in(0, 32, 0, 8) + max_in(0, 32, 25, 32);
  std::printf("bump maxima: density 0.9 %.3f m, density 0.3 %.3f m, far from plants %.3f m\n",
              dense, sparse, far);
  EXPECT_GT(dense, 0.6 * p.bump_height_m());
  EXPECT_LE(dense, 0.9 * p.bump_height_m() + 1e-6);
  EXPECT_GT(sparse, 0.1 * p.bump_height_m());
  EXPECT_LT(sparse, 0.5 * dense);
  EXPECT_LT(far, 1e-3 * p.bump_height_m());
  // The lee tail: 2 to 4 cells beyond the plants (cells 6 to 10), more
  // sand downwind (+x) than upwind.
  double up = 0, down = 0;
  for (int j = 12 * 4; j < 21 * 4; ++j) {
    for (int i = 2 * 4; i < 4 * 4; ++i) up += a.bumps[static_cast<size_t>(j) * a.nx + i];
    for (int i = 13 * 4; i < 15 * 4; ++i) down += a.bumps[static_cast<size_t>(j) * a.nx + i];
  }
  std::printf("bump volume 2-4 cells upwind %.3f, downwind %.3f (cell units)\n", up, down);
  EXPECT_GT(down, up);
  // The bumps are in the amplified height.
  EXPECT_GT(a.height[static_cast<size_t>(16 * 4) * a.nx + 8 * 4] -
                a.base[static_cast<size_t>(16 * 4) * a.nx + 8 * 4],
            0.0f);
}

TEST(Bumps, AroundObstaclesOnlyWhenTheDatasetExists) {
  AmplifyParams p = defaults();
  p.set_ripple_height_m(0);
  AmplifyInput in = flat_sand(kCoarse, 5, 0);
  const AmplifiedLayers none = amplify_layers(in, kAll, 4, p);
  for (float b : none.bumps) EXPECT_EQ(b, 0.0f);
  in.obstacles.assign(static_cast<size_t>(kCoarse) * kCoarse, 0.0f);
  in.obstacles[8 * kCoarse + 8] = 1;
  const AmplifiedLayers with = amplify_layers(in, kAll, 4, p);
  double m = 0;
  for (float b : with.bumps) m = std::max(m, static_cast<double>(b));
  EXPECT_NEAR(m, p.obstacle_bump_height_m(), 0.05 * p.obstacle_bump_height_m());
}

TEST(Amplify, ReadsASnapshotWithItsWindHistory) {
  erg::test_support::TempDir dir;
  const int n = kCoarse;
  const std::string job = R"({"domain": {"nx": 16, "ny": 16, "cell_size_m": 1},
    "wind": {"bidirectional": {"speed_mps": 6, "direction_deg": 0, "angle_deg": 180,
                               "period_steps": 10}}, "seed": 5})";
  erg::v1::JobSpec spec = erg::job::parse_json(job);
  erg::job::apply_defaults(spec);
  erg::io::SnapshotMeta meta;
  meta.step = 200;
  meta.nx = meta.ny = n;
  meta.cell_size_m = 1;
  meta.job_spec_json = erg::job::to_json(spec);
  meta.seed = 5;
  const AmplifyInput flat = flat_sand(n, 6, 0);
  erg::io::SnapshotFields f;
  f[erg::fields::kBedrock].data = flat.bedrock.data();
  f[erg::fields::kSand].data = flat.sand.data();
  f[erg::fields::kVegetation].data = flat.vegetation.data();
  f[erg::fields::kWindX] = {flat.wind.data(), 2, 0};
  f[erg::fields::kWindY] = {flat.wind.data(), 2, 1};
  f[erg::fields::kShadow].data = flat.shadow.data();
  const std::string path = dir / "step.h5";
  erg::io::write_snapshot(path, meta, f);

  erg::v1::JobSpec read_spec;
  const AmplifyInput in = input_from_snapshot(path, read_spec);
  EXPECT_TRUE(in.obstacles.empty());
  ASSERT_EQ(in.wind_history.size(), 100u);  // amplify.wind_history_steps
  int east = 0, west = 0;
  for (const Vec2& w : in.wind_history) (w.x > 0 ? east : west) += 1;
  EXPECT_EQ(east, 50);
  EXPECT_EQ(west, 50);
  EXPECT_EQ(in.seed, 5u);
  const std::vector<float> h = amplify(in, kAll, 4, read_spec.amplify());
  EXPECT_EQ(h.size(), static_cast<size_t>(64 * 64));

  // The snapshot's /obstacles holds heights in metres; amplification sees
  // where they are (1) and where they are not (0).
  std::vector<float> obstacle_heights(static_cast<size_t>(n) * n, 0.0f);
  obstacle_heights[3 * n + 5] = 2.5f;
  obstacle_heights[7 * n + 1] = 0.2f;
  f[erg::fields::kObstacles].data = obstacle_heights.data();
  const std::string with_path = dir / "with_obstacles.h5";
  erg::io::write_snapshot(with_path, meta, f);
  const AmplifyInput with = input_from_snapshot(with_path, read_spec);
  ASSERT_EQ(with.obstacles.size(), obstacle_heights.size());
  for (size_t c = 0; c < obstacle_heights.size(); ++c)
    EXPECT_EQ(with.obstacles[c], obstacle_heights[c] > 0 ? 1.0f : 0.0f) << "cell " << c;
}

}  // namespace
