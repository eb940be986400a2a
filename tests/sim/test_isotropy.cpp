// SPDX-License-Identifier: Apache-2.0
// The lattice does not show (docs/dune-forms.md, "Isotropy"): the wind
// shadow's cubic samples (exact on cells and for quadratic surfaces) and
// the slope avalanching holds at repose, the same whatever direction a slope
// faces on the grid, against the [N24] neighbour pairs it replaced, which
// do show the lattice (so that the test can fail).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/grid.h"
#include "sim_test_util.h"
#include "stages/wind_shadow.h"

namespace erg::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

// --- the shadow's samples ------------------------------------------------------------

TEST(Isotropy, CubicSamplesAreExactOnCellsAndForQuadraticSurfaces) {
  const int n = 12, halo = 3, pitch = n + 2 * halo;
  std::vector<float> h(static_cast<size_t>(pitch) * pitch);
  auto at = [&](int x, int y) -> float& {
    return h[static_cast<size_t>(y + halo) * pitch + (x + halo)];
  };
  // A quadratic surface (Keys' kernel reproduces polynomials up to degree 2).
  auto q = [](double x, double y) { return 0.3 + 0.2 * x - 0.1 * y + 0.05 * x * x + 0.02 * x * y; };
  for (int y = -halo; y < n + halo; ++y)
    for (int x = -halo; x < n + halo; ++x) at(x, y) = static_cast<float>(q(x, y));
  const float* base = h.data() + static_cast<size_t>(halo) * pitch + halo;
  for (int y = 2; y < 8; ++y)
    for (int x = 2; x < 8; ++x) {
      ASSERT_EQ(wind_shadow::cubic(base, pitch, x, y, 0.0f, 0.0f), at(x, y));
      for (const float dx : {-1.75f, -0.5f, 0.3f, 1.1f})
        for (const float dy : {-1.25f, 0.5f, 0.9f}) {
          EXPECT_NEAR(wind_shadow::cubic(base, pitch, x, y, dx, dy), q(x + dx, y + dy), 2e-5)
              << "at (" << x << " + " << dx << ", " << y << " + " << dy << ")";
        }
    }
  // The weights sum to 1 at every fraction, and the negative ones to at most
  // 1/8 per axis (what sample_bound allows for).
  for (float t = 0.0f; t < 1.0f; t += 1.0f / 64) {
    const wind_shadow::Cubic w = wind_shadow::cubic_weights(t);
    EXPECT_NEAR(w.w[0] + w.w[1] + w.w[2] + w.w[3], 1.0f, 1e-6f);
    EXPECT_LE(-(std::min(w.w[0], 0.0f) + std::min(w.w[3], 0.0f)), 0.125f + 1e-7f);
  }
}

// --- the angle of repose ----------------------------------------------------------------

// A 40 m column of sand collapses (no wind) into a cone. The slope of its
// flank, from the Sobel gradient of the heights (exact on planes), binned by
// the direction the flank faces, folded onto 0-45 degrees: near an axis
// (0-7.5), in between (15-30) and near a diagonal (37.5-45). Medians over the
// cells between 10% and 90% of the cone's height.
struct Flank {
  double axis, between, diagonal;
};
Flank cone_flank(const std::string& repose) {
  const int n = 160;
  Simulation sim(spec_from(R"({
      "domain": {"nx": 160, "ny": 160, "cell_size_m": 1.0},
      "layers": {"sand": {"piles": [{"x_m": 80, "y_m": 80, "height": 40, "radius_m": 12,
                                      "shape": "CYLINDER"}]}},
      "wind": {"constant": {"speed_mps": 0}},
      "model": {"repose": ")" +
                           repose + R"(", "avalanche_iterations": 200000},
      "run": {"steps": 1}})"),
                 ".", cpu_threads(2));
  sim.step();
  EXPECT_EQ(sim.times().avalanche_capped_steps, 0) << repose << ": the cone did not settle";
  const auto h = heights_m(sim.state());
  auto H = [&](int x, int y) { return h[static_cast<size_t>(y) * n + x]; };
  const double top = *std::max_element(h.begin(), h.end());
  std::vector<double> bins[3];
  for (int y = 1; y < n - 1; ++y)
    for (int x = 1; x < n - 1; ++x) {
      if (H(x, y) < 0.1 * top || H(x, y) > 0.9 * top) continue;
      const double gx = ((H(x + 1, y - 1) + 2 * H(x + 1, y) + H(x + 1, y + 1)) -
                         (H(x - 1, y - 1) + 2 * H(x - 1, y) + H(x - 1, y + 1))) /
                        8;
      const double gy = ((H(x - 1, y + 1) + 2 * H(x, y + 1) + H(x + 1, y + 1)) -
                         (H(x - 1, y - 1) + 2 * H(x, y - 1) + H(x + 1, y - 1))) /
                        8;
      double phi = std::atan2(std::fabs(gy), std::fabs(gx)) * 180 / kPi;  // 0-90
      if (phi > 45) phi = 90 - phi;
      const double slope = std::atan(std::hypot(gx, gy)) * 180 / kPi;
      if (phi <= 7.5) bins[0].push_back(slope);
      if (phi >= 15 && phi <= 30) bins[1].push_back(slope);
      if (phi >= 37.5) bins[2].push_back(slope);
    }
  auto median = [](std::vector<double> v) {
    EXPECT_GT(v.size(), 40u);
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  return {median(bins[0]), median(bins[1]), median(bins[2])};
}

// [N24] eq. 9's neighbour pairs hold the flank facing between an axis and a
// diagonal up to 2 degrees steeper than the 33 degrees it holds facing an
// axis or a diagonal (an octagonal cone); the isotropic repose holds 33
// degrees facing any direction.
TEST(Isotropy, ACollapsedColumnStandsAtReposeFacingAnyDirection) {
  const Flank iso = cone_flank("ISOTROPIC"), pairs = cone_flank("NEIGHBOUR_PAIRS");
  auto text = [](const Flank& f) {
    return "axis " + std::to_string(f.axis) + ", between " + std::to_string(f.between) +
           ", diagonal " + std::to_string(f.diagonal) + " deg";
  };
  RecordProperty("isotropic", text(iso));
  RecordProperty("neighbour_pairs", text(pairs));
  for (const double s : {iso.axis, iso.between, iso.diagonal})
    EXPECT_NEAR(s, 33.0, 0.75) << "isotropic: " << text(iso);
  EXPECT_LT(std::fabs(iso.between - iso.axis), 0.5) << text(iso);
  EXPECT_LT(std::fabs(iso.between - iso.diagonal), 0.5) << text(iso);
  EXPECT_GT(pairs.between - pairs.axis, 1.0) << "neighbour pairs: " << text(pairs);
  EXPECT_GT(pairs.between - pairs.diagonal, 1.0) << "neighbour pairs: " << text(pairs);
}

}  // namespace
}  // namespace erg::test
