// SPDX-License-Identifier: Apache-2.0
// Local wind primitives ([P19] 4.4, stages/wind_primitives.h): the discrete
// curl of psi has no discrete divergence (the matching corner operator), also
// across the torus seam; a vortex turns the right way with the right peak;
// turbulence has the rms speed asked for; the time envelope, events that add
// and remove primitives; the perturbation is in the wind the snapshots write.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "sim_test_util.h"
#include "stages/wind_primitives.h"
#include "wind/primitives.h"

namespace erg::test {
namespace {

namespace wp = wind_primitives;

// A 64 x 48 domain of 1 m cells (the validator's limits hold for these).
const char* kDomain = R"("domain": {"nx": 64, "ny": 48, "cell_size_m": 1.0},
                         "wind": {"constant": {"speed_mps": 0}})";

erg::v1::JobSpec job_with(const std::string& rest) {
  return spec_from(std::string("{") + kDomain + ", " + rest + "}");
}

struct Field2 {
  int nx, ny;
  std::vector<wp::Velocity> u;  // as the wind stores them: float
  wp::Velocity at(int x, int y) const {
    x = (x % nx + nx) % nx;
    y = (y % ny + ny) % ny;
    return u[static_cast<size_t>(y) * nx + x];
  }
};

Field2 sample(const std::vector<wp::Primitive>& prims, int nx, int ny) {
  Field2 f{nx, ny, {}};
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x) {
      Vec2 w{0, 0};
      for (const auto& b : wind::batches(prims)) w = wp::add_batch(w, b, x, y);
      f.u.push_back({w.x, w.y});
    }
  return f;
}

struct DivCurl {
  double max_div = 0, max_curl = 0, max_speed = 0;
};

// The matching divergence and the vorticity at every corner, wrapping.
DivCurl div_curl(const Field2& f, double l) {
  DivCurl r;
  for (int j = 0; j < f.ny; ++j)
    for (int i = 0; i < f.nx; ++i) {
      const wp::Velocity u00 = f.at(i - 1, j - 1), u10 = f.at(i, j - 1), u01 = f.at(i - 1, j),
                         u11 = f.at(i, j);
      r.max_div = std::max(r.max_div, std::fabs(wp::divergence_at_corner(u00, u10, u01, u11, l)));
      const double inv = 0.5 / l;  // D_x u_y - D_y u_x, the same averaging
      const double curl =
          ((u10.y + u11.y) - (u00.y + u01.y)) * inv - ((u01.x + u11.x) - (u00.x + u10.x)) * inv;
      r.max_curl = std::max(r.max_curl, std::fabs(curl));
      r.max_speed = std::max(r.max_speed, std::hypot(u11.x, u11.y));
    }
  return r;
}

TEST(WindPrimitives, VortexOnTheSeamIsDivergenceFree) {
  // Centred on the corner of the domain: it straddles both seams.
  for (const char* rot : {"COUNTERCLOCKWISE", "CLOCKWISE"}) {
    const auto spec = job_with(std::string(R"("wind_primitives": [{"vortex": {"x_m": 1.3,
        "y_m": 46.5, "radius_m": 6, "peak_speed_mps": 4, "falloff_exponent": 3, "rotation": ")") +
                               rot + R"("}}])");
    const auto prims = wind::primitives_at(spec, 0);
    ASSERT_EQ(prims.size(), 1u);
    const DivCurl d = div_curl(sample(prims, 64, 48), 1.0);
    EXPECT_GT(d.max_curl, 0.5) << rot;
    EXPECT_LT(d.max_div, 1e-5 * d.max_curl) << rot << ": max |div| " << d.max_div;
  }
}

TEST(WindPrimitives, TurbulenceIsDivergenceFreeAndSeamless) {
  // The whole domain (periodic noise), and a region over the seam, drifting
  // and evolving (both noise fields blended).
  for (const std::string prim :
       {R"({"turbulence": {"amplitude_mps": 3, "wavelength_m": 12}})",
        R"({"start_step": 2, "turbulence": {"amplitude_mps": 2, "wavelength_m": 10, "x_m": 60,
            "y_m": 5, "radius_m": 20, "falloff_m": 8, "period_steps": 40,
            "drift_m_per_step": 0.7, "drift_direction_deg": 33, "seed_offset": 5}})"}) {
    const auto spec = job_with(R"("wind_primitives": [)" + prim + "]");
    const auto prims = wind::primitives_at(spec, 7);
    ASSERT_EQ(prims.size(), 1u);
    const Field2 f = sample(prims, 64, 48);
    const DivCurl d = div_curl(f, 1.0);
    EXPECT_GT(d.max_curl, 0.3) << prim;
    EXPECT_LT(d.max_div, 1e-5 * d.max_curl) << prim << ": max |div| " << d.max_div;
    // Seamless: the jump across the seam is no larger than between neighbours.
    double inner = 0, seam = 0;
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x) {
        const wp::Velocity a = f.at(x, y), b = f.at(x + 1, y), c = f.at(x, y + 1);
        const double jump =
            std::max(std::hypot(a.x - b.x, a.y - b.y), std::hypot(a.x - c.x, a.y - c.y));
        double& worst = x == 63 || y == 47 ? seam : inner;
        worst = std::max(worst, jump);
      }
    EXPECT_GT(inner, 0.0);
    EXPECT_LE(seam, inner) << prim;
  }
}

TEST(WindPrimitives, VortexTurnsTheRightWayWithItsPeakSpeedAtItsRadius) {
  // Centre on a corner at (32, 24); R = 8 m: cell (39, 24) has its centre at
  // (7.5, 0.5) from the centre, cell (24, 23) at (-7.5, -0.5).
  for (const bool ccw : {true, false}) {
    const auto spec = job_with(std::string(R"("wind_primitives": [{"vortex": {"x_m": 32,
        "y_m": 24, "radius_m": 8, "peak_speed_mps": 5)") +
                               (ccw ? "" : R"(, "rotation": "CLOCKWISE")") + "}}]");
    const Field2 f = sample(wind::primitives_at(spec, 0), 64, 48);
    const double s = ccw ? 1.0 : -1.0;
    EXPECT_GT(s * f.at(39, 24).y, 4.5) << "east of the centre, ccw blows north";
    EXPECT_GT(-s * f.at(24, 23).y, 4.5) << "west of the centre, ccw blows south";
    EXPECT_GT(-s * f.at(31, 31).x, 4.5) << "north of the centre, ccw blows west";
    EXPECT_LT(std::fabs(f.at(39, 24).x), 0.6);
    // Peak speed and where it is.
    double peak = 0, r_at_peak = 0;
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x) {
        const wp::Velocity u = f.at(x, y);
        const double v = std::hypot(u.x, u.y);
        if (v > peak) {
          peak = v;
          r_at_peak = std::hypot(x + 0.5 - 32, y + 0.5 - 24);
        }
      }
    EXPECT_NEAR(peak, 5.0, 0.1);
    EXPECT_NEAR(r_at_peak, 8.0, 1.0);
    // Calm at the centre and far away.
    EXPECT_LT(std::hypot(f.at(32, 24).x, f.at(32, 24).y), 0.8);  // r = 0.7 m
    EXPECT_LT(std::hypot(f.at(0, 0).x, f.at(0, 0).y), 0.01);
  }
}

TEST(WindPrimitives, TurbulenceHasTheRmsSpeedAskedFor) {
  const auto spec = job_with(R"("wind_primitives": [{"turbulence": {"amplitude_mps": 2.5,
      "wavelength_m": 8, "period_steps": 10}}])");
  for (int step : {0, 3}) {
    const Field2 f = sample(wind::primitives_at(spec, step), 64, 48);
    double sum = 0;
    for (const auto& u : f.u) sum += u.x * u.x + u.y * u.y;
    const double rms = std::sqrt(sum / static_cast<double>(f.u.size()));
    EXPECT_NEAR(rms, 2.5, 0.5) << "step " << step;
  }
}

// Envelope at a step of the first primitive (0 when none is active).
double amp_at(const erg::v1::JobSpec& spec, std::int64_t step) {
  const auto prims = wind::primitives_at(spec, step);
  return prims.empty() ? 0.0 : prims.front().amp;
}

TEST(WindPrimitives, StartEndRampsAndEvents) {
  const auto spec = job_with(R"("wind_primitives": [{"name": "v", "start_step": 10,
      "end_step": 30, "ramp_steps": 4, "vortex": {"x_m": 32, "y_m": 24, "radius_m": 8,
      "peak_speed_mps": 5}}])");
  const double full = amp_at(spec, 20);
  EXPECT_GT(full, 0.0);
  EXPECT_EQ(amp_at(spec, 9), 0.0) << "before start_step";
  EXPECT_EQ(amp_at(spec, 30), 0.0) << "at end_step";
  EXPECT_EQ(amp_at(spec, 1000), 0.0) << "after end_step";
  EXPECT_GT(amp_at(spec, 10), 0.0);
  EXPECT_LT(amp_at(spec, 10), amp_at(spec, 11));
  EXPECT_LT(amp_at(spec, 11), full);
  EXPECT_DOUBLE_EQ(amp_at(spec, 14), full) << "ramped up after ramp_steps";
  EXPECT_DOUBLE_EQ(amp_at(spec, 25), full);
  EXPECT_LT(amp_at(spec, 29), full);
  EXPECT_DOUBLE_EQ(amp_at(spec, 10), amp_at(spec, 29)) << "symmetric ramps";
  // Nothing active: a step outside the envelope leaves the wind untouched.
  EXPECT_TRUE(wind::primitives_at(spec, 5).empty());

  // Events: added at step 50 (its steps count from there), removed at 80.
  const auto ev = job_with(R"("events": [
      {"step": 50, "wind_primitive": {"name": "t", "start_step": 5,
       "turbulence": {"amplitude_mps": 1}}},
      {"step": 60, "wind_primitive": {"name": "keep", "vortex": {"x_m": 5, "y_m": 5,
       "radius_m": 4, "peak_speed_mps": 2}}},
      {"step": 80, "remove_wind_primitive": "t"}])");
  EXPECT_TRUE(wind::primitives_at(ev, 54).empty());
  ASSERT_EQ(wind::primitives_at(ev, 55).size(), 1u);
  EXPECT_EQ(wind::primitives_at(ev, 55)[0].kind, wp::kTurbulence);
  EXPECT_EQ(wind::primitives_at(ev, 79).size(), 2u);
  ASSERT_EQ(wind::primitives_at(ev, 80).size(), 1u);
  EXPECT_EQ(wind::primitives_at(ev, 80)[0].kind, wp::kVortex);
}

TEST(WindPrimitives, ManyPrimitivesAddUpAcrossBatches) {
  // Ten vortices (two batches): the field is the sum of the ten single ones.
  std::string list;
  for (int k = 0; k < 10; ++k)
    list += std::string(k ? ", " : "") + R"({"vortex": {"x_m": )" + std::to_string(6 * k + 3) +
            R"(, "y_m": )" + std::to_string(4 * k + 2) +
            R"(, "radius_m": 3, "peak_speed_mps": 1}})";
  const auto prims = wind::primitives_at(job_with(R"("wind_primitives": [)" + list + "]"), 0);
  ASSERT_EQ(prims.size(), 10u);
  ASSERT_EQ(wind::batches(prims).size(), 2u);
  const Field2 all = sample(prims, 64, 48);
  double worst = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      double sx = 0, sy = 0;
      for (const auto& p : prims) {
        const wp::Velocity u = wp::velocity_at(p, x, y);
        sx += u.x;
        sy += u.y;
      }
      worst = std::max(worst, std::hypot(all.at(x, y).x - sx, all.at(x, y).y - sy));
    }
  EXPECT_LT(worst, 1e-5);
  const DivCurl d = div_curl(all, 1.0);
  EXPECT_LT(d.max_div, 1e-5 * d.max_curl);
}

// The perturbation is in the surface wind the snapshots write (/wind): the
// CPU backend's wind (which visits only the primitives' boxes and reuses
// corners) is bit for bit the warped wind plus wind_primitives::add_batch,
// the per-cell function the GPU runs.
TEST(WindPrimitives, PerturbationIsInTheOutputWind) {
  const std::string base = std::string("{") + R"("domain": {"nx": 64, "ny": 48, "cell_size_m": 1.0},
      "layers": {"sand": {"piles": [{"x_m": 20, "y_m": 20, "height": 4, "radius_m": 12}]}},
      "wind": {"constant": {"speed_mps": 3, "direction_deg": 20}},
      "run": {"steps": 1}, )";
  const std::string prims = R"("wind_primitives": [
      {"vortex": {"x_m": 32, "y_m": 24, "radius_m": 8, "peak_speed_mps": 5}},
      {"vortex": {"x_m": 62, "y_m": 1, "radius_m": 5, "peak_speed_mps": 2, "rotation": "CLOCKWISE"}},
      {"turbulence": {"amplitude_mps": 1, "wavelength_m": 10, "x_m": 5, "y_m": 40,
                      "radius_m": 15, "falloff_m": 5, "period_steps": 9}}]})";
  Simulation plain(spec_from(base + R"("seed": 1})"), ".", cpu_threads(2));
  Simulation with(spec_from(base + prims), ".", cpu_threads(2));
  plain.step();
  with.step();
  // The output wind, interleaved (x, y) per cell.
  auto interleaved = [](Simulation& sim) {
    const Simulation::Output o = sim.output();
    std::vector<float> w;
    for (size_t c = 0; c < o[fields::kWindX].size(); ++c) {
      w.push_back(o[fields::kWindX][c]);
      w.push_back(o[fields::kWindY][c]);
    }
    return w;
  };
  const auto a = interleaved(plain), b = interleaved(with);
  const auto batches = wind::batches(wind::primitives_at(with.spec(), 0));
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].n, 3);
  long differ = 0, changed = 0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) {
      const size_t i = 2 * (static_cast<size_t>(y) * 64 + x);
      const Vec2 want = wp::add_batch({a[i], a[i + 1]}, batches[0], x, y);
      differ += want.x != b[i] || want.y != b[i + 1];
      changed += a[i] != b[i] || a[i + 1] != b[i + 1];
    }
  EXPECT_EQ(differ, 0);
  EXPECT_GT(changed, 500);
  // The vortex's north-bound side, on top of the 3 m/s wind.
  const size_t east = 2 * (24 * 64 + 39);
  EXPECT_GT(b[east + 1] - a[east + 1], 4.5f);
}

}  // namespace
}  // namespace erg::test
