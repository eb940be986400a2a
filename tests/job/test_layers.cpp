// SPDX-License-Identifier: Apache-2.0
// Initial-layer generators (init::generate_layer): every generator gives a
// global cell the same value whatever tile computes it; fBm wraps smoothly;
// sand patches reach their coverage; uniform values lie in [min, max); piles
// have the right shape and wrap; maps are read with offset, scale and the
// right orientation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/grid.h"
#include "init/layers.h"
#include "job/spec.h"
#include "job_test_util.h"

namespace erg::init {
namespace {

using erg::job::testing::TempDir;
using erg::v1::JobSpec;
using erg::v1::Layer;

JobSpec domain_spec(int nx, int ny, double cell, std::int64_t seed = 1) {
  JobSpec s = erg::job::parse_json(R"({"wind": {"constant": {"speed_mps": 1}}})");
  s.mutable_domain()->set_nx(nx);
  s.mutable_domain()->set_ny(ny);
  s.mutable_domain()->set_cell_size_m(cell);
  s.set_seed(seed);
  erg::job::apply_defaults(s);
  return s;
}

// A layer from its JSON, with defaults (as the job would give it).
Layer layer_of(const std::string& json) {
  JobSpec s = erg::job::parse_json(R"({"layers": {"sand": )" + json + "}}");
  erg::job::apply_defaults(s);
  return s.layers().sand();
}

TileGeom sub_tile(const JobSpec& spec, int x0, int y0, int nx, int ny) {
  TileGeom t = make_single_tile(nx, ny, 2, static_cast<float>(spec.domain().cell_size_m()));
  t.x0 = x0;
  t.y0 = y0;
  t.gnx = static_cast<int>(spec.domain().nx());
  t.gny = static_cast<int>(spec.domain().ny());
  return t;
}

std::vector<double> whole(const Layer& layer, const JobSpec& spec,
                          LayerKind kind = LayerKind::kSand, const std::string& base_dir = ".") {
  const int nx = static_cast<int>(spec.domain().nx()), ny = static_cast<int>(spec.domain().ny());
  return generate_layer(
      layer, kind, spec,
      make_single_tile(nx, ny, 2, static_cast<float>(spec.domain().cell_size_m())), base_dir);
}

// The global field assembled from the tiles cut at xs x ys (each list starts
// at 0 and ends at the domain size).
std::vector<double> tiled(const Layer& layer, const JobSpec& spec, const std::vector<int>& xs,
                          const std::vector<int>& ys, const std::string& base_dir = ".",
                          LayerKind kind = LayerKind::kSand) {
  const int gnx = static_cast<int>(spec.domain().nx());
  std::vector<double> out(static_cast<size_t>(gnx) * spec.domain().ny(), std::nan(""));
  for (size_t j = 0; j + 1 < ys.size(); ++j)
    for (size_t i = 0; i + 1 < xs.size(); ++i) {
      const TileGeom t = sub_tile(spec, xs[i], ys[j], xs[i + 1] - xs[i], ys[j + 1] - ys[j]);
      const std::vector<double> v = generate_layer(layer, kind, spec, t, base_dir);
      EXPECT_EQ(v.size(), static_cast<size_t>(t.nx) * t.ny);
      for (int y = 0; y < t.ny; ++y)
        for (int x = 0; x < t.nx; ++x)
          out[static_cast<size_t>(t.y0 + y) * gnx + t.x0 + x] =
              v[static_cast<size_t>(y) * t.nx + x];
    }
  return out;
}

// Number of cells where two fields differ at all (bitwise comparison of values).
int differing_cells(const std::vector<double>& a, const std::vector<double>& b) {
  EXPECT_EQ(a.size(), b.size());
  int n = 0;
  for (size_t k = 0; k < std::min(a.size(), b.size()); ++k)
    if (!(a[k] == b[k])) ++n;
  return n;
}

double at(const std::vector<double>& f, const JobSpec& spec, int x, int y) {
  return f[static_cast<size_t>(y) * spec.domain().nx() + x];
}

double mean_of(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

// ---- tiling independence ------------------------------------------------------------

struct TilingCase {
  const char* name;
  const char* layer;
};

class TilingIndependence : public ::testing::TestWithParam<TilingCase> {};

TEST_P(TilingIndependence, SameValueWhateverTileComputesIt) {
  const JobSpec spec = domain_spec(96, 80, 0.5, 77);
  const Layer layer = layer_of(GetParam().layer);
  const std::vector<double> ref = whole(layer, spec);
  ASSERT_EQ(ref.size(), 96u * 80u);
  // Uneven tiles, then a regular 4 x 4 split.
  EXPECT_EQ(differing_cells(ref, tiled(layer, spec, {0, 40, 70, 96}, {0, 33, 80})), 0);
  EXPECT_EQ(differing_cells(ref, tiled(layer, spec, {0, 24, 48, 72, 96}, {0, 20, 40, 60, 80})), 0);
  EXPECT_EQ(differing_cells(ref, tiled(layer, spec, {0, 1, 95, 96}, {0, 79, 80})), 0);
  // The field is not trivially constant (except for the constant source).
  const auto [lo, hi] = std::minmax_element(ref.begin(), ref.end());
  if (std::string(GetParam().name) != "Constant") {
    EXPECT_LT(*lo, *hi);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Generators, TilingIndependence,
    ::testing::Values(
        TilingCase{"Constant", R"({"constant": 2.5})"},
        TilingCase{"Fbm", R"({"fbm": {"wavelength_m": 16, "octaves": 4}})"},
        TilingCase{"FbmRidgedAnisotropic",
                   R"({"fbm": {"wavelength_m": 10, "ridged": true, "anisotropy": 2.5}})"},
        TilingCase{"Uniform", R"({"uniform": {"min": -1, "max": 2}})"},
        TilingCase{"Patches", R"({"patches": {"coverage": 0.3, "radius_m": 2.5, "falloff_m": 1}})"},
        TilingCase{"PatchesLargerThanTiles",
                   R"({"patches": {"coverage": 0.5, "radius_m": 9, "falloff_m": 4}})"},
        TilingCase{"Piles", R"({"piles": [
            {"x_m": 0.2, "y_m": 39.9, "height": 3, "radius_m": 6},
            {"x_m": 24, "y_m": 20, "height": 2, "radius_m": 5, "shape": "GAUSSIAN"},
            {"x_m": 47, "y_m": 1, "height": -1, "radius_m": 4, "shape": "CYLINDER"}]})"},
        TilingCase{"AllSources", R"({"constant": 1, "fbm": {"wavelength_m": 12},
            "uniform": {"max": 0.1}, "patches": {"coverage": 0.2, "radius_m": 3},
            "piles": [{"x_m": 10, "y_m": 10, "height": 2, "radius_m": 8}]})"}),
    [](const ::testing::TestParamInfo<TilingCase>& i) { return std::string(i.param.name); });

TEST(Generators, MapsAreTilingIndependent) {
  TempDir dir;
  const JobSpec spec = domain_spec(96, 80, 0.5);
  std::vector<double> raw(96 * 80);
  for (size_t k = 0; k < raw.size(); ++k) raw[k] = std::sin(0.37 * static_cast<double>(k));
  erg::job::testing::write_h5_doubles(dir.file("m.h5"), "/data", 96, 80, raw);
  std::vector<std::uint16_t> png(96 * 80);
  for (size_t k = 0; k < png.size(); ++k) png[k] = static_cast<std::uint16_t>(k * 7919 % 65536);
  erg::job::testing::write_png16_raw(dir.file("m.png"), 96, 80, png);
  // seam_tolerance 1: the sine rows do not wrap smoothly (not what is tested here).
  for (const char* json : {R"({"map": {"path": "m.h5", "scale": 3, "offset": -1,
                                       "seam_tolerance": 1}})",
                           R"({"map": {"path": "m.png", "scale": 10, "offset": 2,
                                       "seam_tolerance": 1}})"}) {
    const Layer layer = layer_of(json);
    const auto ref = whole(layer, spec, LayerKind::kBedrock, dir.str());
    EXPECT_EQ(differing_cells(ref, tiled(layer, spec, {0, 40, 70, 96}, {0, 33, 80}, dir.str())), 0)
        << json;
  }
}

TEST(Generators, RandomSourcesDependOnSeedKindAndSeedOffset) {
  const JobSpec spec = domain_spec(64, 64, 1, 5);
  const JobSpec other_seed = domain_spec(64, 64, 1, 6);
  for (const char* json : {R"({"fbm": {"wavelength_m": 16}})", R"({"uniform": {}})",
                           R"({"patches": {"coverage": 0.3, "radius_m": 3}})"}) {
    const Layer layer = layer_of(json);
    const auto sand = whole(layer, spec, LayerKind::kSand);
    EXPECT_EQ(differing_cells(sand, whole(layer, spec, LayerKind::kSand)), 0) << json;
    EXPECT_GT(differing_cells(sand, whole(layer, other_seed, LayerKind::kSand)), 64 * 64 / 10)
        << json;
    EXPECT_GT(differing_cells(sand, whole(layer, spec, LayerKind::kBedrock)), 64 * 64 / 10) << json;
  }
  Layer a = layer_of(R"({"uniform": {"seed_offset": 0}})");
  Layer b = layer_of(R"({"uniform": {"seed_offset": 3}})");
  EXPECT_GT(differing_cells(whole(a, spec), whole(b, spec)), 64 * 64 / 2);
  a = layer_of(R"({"fbm": {"seed_offset": 0, "wavelength_m": 16}})");
  b = layer_of(R"({"fbm": {"seed_offset": 3, "wavelength_m": 16}})");
  EXPECT_GT(differing_cells(whole(a, spec), whole(b, spec)), 64 * 64 / 2);
}

TEST(Generators, NoSourceGivesZero) {
  const JobSpec spec = domain_spec(16, 8, 1);
  for (double v : whole(Layer(), spec)) EXPECT_EQ(v, 0.0);
  for (double v : whole(layer_of(R"({"constant": -2.5})"), spec)) EXPECT_EQ(v, -2.5);
}

// ---- fBm -------------------------------------------------------------------------------

// Jumps between neighbouring cells along x or y: the mean jump of each line
// of neighbour pairs (i, i + 1) across the other axis, and the largest single
// jump, inside the domain and across the periodic edge (n - 1, 0).
struct Roughness {
  double interior_mean = 0;      // mean over all interior pairs
  double interior_line_max = 0;  // largest mean of one interior line of pairs
  double interior_max = 0;       // largest interior jump
  double wrap_mean = 0, wrap_max = 0;
};

Roughness roughness(const std::vector<double>& f, int nx, int ny, bool along_x) {
  Roughness r;
  const int n = along_x ? nx : ny, m = along_x ? ny : nx;
  auto v = [&](int i, int j) {
    return along_x ? f[static_cast<size_t>(j) * nx + i] : f[static_cast<size_t>(i) * nx + j];
  };
  for (int i = 0; i < n; ++i) {
    const int k = (i + 1) % n;
    double line = 0, line_max = 0;
    for (int j = 0; j < m; ++j) {
      const double d = std::fabs(v(k, j) - v(i, j));
      line += d;
      line_max = std::max(line_max, d);
    }
    line /= m;
    if (k == 0) {
      r.wrap_mean = line;
      r.wrap_max = line_max;
    } else {
      r.interior_mean += line / (n - 1);
      r.interior_line_max = std::max(r.interior_line_max, line);
      r.interior_max = std::max(r.interior_max, line_max);
    }
  }
  return r;
}

void expect_tileable(const std::string& json, int nx, int ny, double cell) {
  SCOPED_TRACE(json);
  const JobSpec spec = domain_spec(nx, ny, cell, 9);
  const auto f = whole(layer_of(json), spec);
  double mean = mean_of(f), var = 0;
  for (double v : f) var += (v - mean) * (v - mean);
  var /= static_cast<double>(f.size());
  EXPECT_GT(std::sqrt(var), 0.05) << "the field is (nearly) flat";
  for (bool along_x : {true, false}) {
    const Roughness r = roughness(f, nx, ny, along_x);
    SCOPED_TRACE(along_x ? "along x" : "along y");
    // A field that did not wrap would jump by about its amplitude at the edge,
    // many times a typical neighbour difference.
    EXPECT_LE(r.wrap_mean, 1.1 * r.interior_line_max)
        << "wrap " << r.wrap_mean << " vs interior lines up to " << r.interior_line_max << " (mean "
        << r.interior_mean << ")";
    EXPECT_LE(r.wrap_max, 1.1 * r.interior_max)
        << "wrap " << r.wrap_max << " vs interior " << r.interior_max;
  }
}

TEST(Fbm, IsTileable) {
  expect_tileable(R"({"fbm": {"wavelength_m": 64, "octaves": 3}})", 128, 128, 1);
  // Wavelengths that do not divide the domain: the lattice period is rounded.
  expect_tileable(R"({"fbm": {"wavelength_m": 30, "octaves": 2, "amplitude": 5}})", 100, 60, 1);
  expect_tileable(R"({"fbm": {"wavelength_m": 23, "octaves": 3, "anisotropy": 3}})", 90, 70, 0.8);
  expect_tileable(R"({"fbm": {"wavelength_m": 40, "octaves": 2, "ridged": true}})", 120, 96, 1);
}

TEST(Fbm, AmplitudeOffsetAndRange) {
  const JobSpec spec = domain_spec(128, 128, 1, 3);
  const auto base = whole(layer_of(R"({"fbm": {"wavelength_m": 32, "octaves": 1}})"), spec);
  const auto scaled = whole(
      layer_of(R"({"fbm": {"wavelength_m": 32, "octaves": 1, "amplitude": 4, "offset": 10}})"),
      spec);
  double lo = 1e9, hi = -1e9;
  for (size_t k = 0; k < base.size(); ++k) {
    EXPECT_NEAR(scaled[k], 10 + 4 * base[k], 1e-9);
    lo = std::min(lo, base[k]);
    hi = std::max(hi, base[k]);
  }
  // One octave of noise scaled to about [-1, 1]: spans a good part of it.
  EXPECT_GE(lo, -1.05);
  EXPECT_LE(hi, 1.05);
  EXPECT_GT(hi - lo, 0.8);
  EXPECT_NEAR(mean_of(base), 0.0, 0.2);
  // Ridged noise lies in [-1, 1] as well.
  for (double v :
       whole(layer_of(R"({"fbm": {"wavelength_m": 32, "octaves": 1, "ridged": true}})"), spec)) {
    EXPECT_GE(v, -1.0);
    EXPECT_LE(v, 1.0);
  }
}

// ---- uniform -------------------------------------------------------------------------

TEST(Uniform, ValuesLieInMinMaxWithTheRightMoments) {
  const JobSpec spec = domain_spec(256, 256, 1, 11);
  const auto f = whole(layer_of(R"({"uniform": {"min": -2, "max": 3}})"), spec);
  double lo = 1e9, hi = -1e9, var = 0, corr = 0;
  std::vector<int> hist(10, 0);
  const double mean = mean_of(f);
  for (size_t k = 0; k < f.size(); ++k) {
    ASSERT_GE(f[k], -2.0) << k;
    ASSERT_LT(f[k], 3.0) << k;
    lo = std::min(lo, f[k]);
    hi = std::max(hi, f[k]);
    var += (f[k] - mean) * (f[k] - mean);
    if (k % 256 != 255) corr += (f[k] - mean) * (f[k + 1] - mean);
    ++hist[static_cast<size_t>((f[k] + 2) / 5 * 10)];
  }
  var /= static_cast<double>(f.size());
  corr /= static_cast<double>(f.size()) * var;
  EXPECT_NEAR(mean, 0.5, 0.03);         // standard error 0.0056
  EXPECT_NEAR(var, 25.0 / 12.0, 0.05);  // standard error ~0.009
  EXPECT_LT(std::fabs(corr), 0.02);     // neighbours are independent
  EXPECT_LT(lo, -1.99);
  EXPECT_GT(hi, 2.99);
  for (int h : hist) EXPECT_NEAR(h / static_cast<double>(f.size()), 0.1, 0.006);
}

TEST(Uniform, EqualMinAndMaxIsConstant) {
  const JobSpec spec = domain_spec(16, 16, 1);
  for (double v : whole(layer_of(R"({"uniform": {"min": 0.25, "max": 0.25}})"), spec))
    EXPECT_EQ(v, 0.25);
}

// ---- sand patches --------------------------------------------------------------------

double coverage(const std::vector<double>& f) {
  size_t n = 0;
  for (double v : f) n += v > 0;
  return static_cast<double>(n) / static_cast<double>(f.size());
}

TEST(Patches, ReachTheirTargetCoverage) {
  const JobSpec spec = domain_spec(512, 512, 1, 21);
  for (double target : {0.1, 0.3, 0.6}) {
    const std::string json = R"({"patches": {"coverage": )" + std::to_string(target) +
                             R"(, "radius_m": 4, "falloff_m": 1, "height": 2}})";
    const auto f = whole(layer_of(json), spec);
    EXPECT_NEAR(coverage(f), target, 0.03) << json;
    double hi = 0;
    for (double v : f) {
      ASSERT_GE(v, 0.0);
      hi = std::max(hi, v);
    }
    EXPECT_GE(hi, 2.0);  // the flat top of a disk
  }
}

TEST(Patches, CoverageHoldsWithOtherCellSizesAndRadii) {
  // 0.5 m cells, 3 m radius, 200 x 160 cells = 100 m x 80 m.
  const JobSpec spec = domain_spec(200, 160, 0.5, 4);
  const auto f = whole(layer_of(R"({"patches": {"coverage": 0.45, "radius_m": 3}})"), spec);
  EXPECT_NEAR(coverage(f), 0.45, 0.04);
}

TEST(Patches, ZeroCoverageIsBare) {
  const JobSpec spec = domain_spec(64, 64, 1);
  for (double v : whole(layer_of(R"({"patches": {"coverage": 0}})"), spec)) EXPECT_EQ(v, 0.0);
}

TEST(Patches, DiskShapeAndFalloff) {
  // Coverage so low that there is a single disk (n = 1): check its profile.
  const JobSpec spec = domain_spec(64, 64, 1, 2);
  const double r = 10, falloff = 4, h = 3;
  // n = -ln(1 - c) A / (pi r^2) = 1  =>  c = 1 - exp(-pi r^2 / A)
  const double c = 1 - std::exp(-3.14159265358979 * r * r / (64.0 * 64.0));
  const auto f = whole(layer_of(R"({"patches": {"coverage": )" + std::to_string(c) +
                                R"(, "radius_m": 10, "falloff_m": 4, "height": 3}})"),
                       spec);
  int flat = 0, covered = 0;
  for (double v : f) {
    if (v > 0) ++covered;
    if (std::fabs(v - h) < 1e-12) ++flat;
    EXPECT_LE(v, h + 1e-12);
  }
  const double pi = 3.14159265358979;
  EXPECT_NEAR(covered, pi * r * r, 0.08 * pi * r * r);
  EXPECT_NEAR(flat, pi * (r - falloff) * (r - falloff), 0.15 * pi * (r - falloff) * (r - falloff));
}

// ---- piles -----------------------------------------------------------------------------

TEST(Piles, ConeHeightAndBaseRadius) {
  const JobSpec spec = domain_spec(100, 100, 1);
  const auto f = whole(
      layer_of(R"({"piles": [{"x_m": 50.5, "y_m": 50.5, "height": 5, "radius_m": 10}]})"), spec);
  EXPECT_DOUBLE_EQ(at(f, spec, 50, 50), 5.0);
  EXPECT_DOUBLE_EQ(at(f, spec, 55, 50), 2.5);
  EXPECT_DOUBLE_EQ(at(f, spec, 50, 45), 2.5);
  EXPECT_NEAR(at(f, spec, 59, 50), 0.5, 1e-12);
  EXPECT_EQ(at(f, spec, 60, 50), 0.0);
  EXPECT_NEAR(at(f, spec, 53, 54), 5 * (1 - 5.0 / 10), 1e-12);
  double volume = 0, reach = 0;
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x) {
      const double v = at(f, spec, x, y);
      ASSERT_GE(v, 0.0);
      volume += v;
      if (v > 0) reach = std::max(reach, std::hypot(x - 50.0, y - 50.0));
    }
  EXPECT_NEAR(volume, 3.14159265358979 * 100 * 5 / 3, 0.02 * 523.6);
  EXPECT_LT(reach, 10.0);
  EXPECT_GT(reach, 9.0);
}

TEST(Piles, GaussianHeightAndWidth) {
  const JobSpec spec = domain_spec(100, 100, 1);
  const auto f = whole(
      layer_of(
          R"({"piles": [{"x_m": 50.5, "y_m": 50.5, "height": 4, "radius_m": 10, "shape": "GAUSSIAN"}]})"),
      spec);
  EXPECT_DOUBLE_EQ(at(f, spec, 50, 50), 4.0);
  EXPECT_NEAR(at(f, spec, 55, 50), 4 * std::exp(-0.5), 1e-12);  // r / 2 = one sigma
  EXPECT_NEAR(at(f, spec, 60, 50), 4 * std::exp(-2.0), 1e-12);
  EXPECT_NEAR(at(f, spec, 50, 30), 4 * std::exp(-8.0), 1e-12);
  double volume = 0;
  for (double v : f) volume += v;
  EXPECT_NEAR(volume, 2 * 3.14159265358979 * 25 * 4, 0.01 * 628.3);  // 2 pi sigma^2 h
}

TEST(Piles, CylinderIsFlatToItsRadius) {
  const JobSpec spec = domain_spec(100, 100, 1);
  const auto f = whole(
      layer_of(
          R"({"piles": [{"x_m": 50.5, "y_m": 50.5, "height": 2, "radius_m": 10, "shape": "CYLINDER"}]})"),
      spec);
  EXPECT_EQ(at(f, spec, 50, 50), 2.0);
  EXPECT_EQ(at(f, spec, 60, 50), 2.0);  // on the rim
  EXPECT_EQ(at(f, spec, 61, 50), 0.0);
  EXPECT_EQ(at(f, spec, 57, 57), 2.0);  // 9.9 m
  EXPECT_EQ(at(f, spec, 58, 57), 0.0);  // 10.6 m
  double volume = 0;
  for (double v : f) {
    EXPECT_TRUE(v == 0.0 || v == 2.0) << v;
    volume += v;
  }
  EXPECT_NEAR(volume, 3.14159265358979 * 100 * 2, 0.03 * 628.3);
}

TEST(Piles, WrapAcrossTheEdges) {
  const JobSpec spec = domain_spec(100, 80, 1);
  // Centre on cell (1, 78) near the north-west corner.
  const auto f = whole(
      layer_of(R"({"piles": [{"x_m": 1.5, "y_m": 78.5, "height": 3, "radius_m": 6}]})"), spec);
  const double two_away = 3 * (1 - 2.0 / 6);
  EXPECT_DOUBLE_EQ(at(f, spec, 1, 78), 3.0);
  EXPECT_NEAR(at(f, spec, 3, 78), two_away, 1e-12);
  EXPECT_NEAR(at(f, spec, 99, 78), two_away, 1e-12);  // across x = 0
  EXPECT_NEAR(at(f, spec, 1, 76), two_away, 1e-12);
  EXPECT_NEAR(at(f, spec, 1, 0), two_away, 1e-12);  // across y = ny
  EXPECT_NEAR(at(f, spec, 97, 0), 3 * (1 - std::sqrt(20.0) / 6), 1e-12);
  EXPECT_EQ(at(f, spec, 50, 40), 0.0);
  // A centre given outside [0, L) wraps too.
  const auto g =
      whole(layer_of(R"({"piles": [{"x_m": -0.5, "y_m": 180.5, "height": 1, "radius_m": 3,
                                                "shape": "CYLINDER"}]})"),
            spec);
  EXPECT_EQ(at(g, spec, 99, 20), 1.0);
  EXPECT_EQ(at(g, spec, 1, 20), 1.0);
  EXPECT_EQ(at(g, spec, 99, 23), 1.0);
  EXPECT_EQ(at(g, spec, 99, 24), 0.0);
}

TEST(Piles, SumWithEachOtherAndTheOtherSources) {
  const JobSpec spec = domain_spec(64, 64, 1);
  const auto f = whole(layer_of(R"({"constant": 1, "piles": [
      {"x_m": 20.5, "y_m": 20.5, "height": 4, "radius_m": 8},
      {"x_m": 24.5, "y_m": 20.5, "height": -2, "radius_m": 8, "shape": "CYLINDER"}]})"),
                       spec);
  EXPECT_DOUBLE_EQ(at(f, spec, 20, 20), 1 + 4 - 2);
  EXPECT_DOUBLE_EQ(at(f, spec, 24, 20), 1 + 4 * 0.5 - 2);
  EXPECT_DOUBLE_EQ(at(f, spec, 31, 20), 1 - 2);
  EXPECT_DOUBLE_EQ(at(f, spec, 50, 50), 1);
}

// ---- maps ------------------------------------------------------------------------------
// The maps below are ramps, whose opposite borders differ: seam_tolerance 1
// accepts them (the tileability test has its own tests in tests/export).

TEST(Maps, Hdf5WithOffsetScaleAndSubTiles) {
  TempDir dir;
  const int nx = 40, ny = 30;
  const JobSpec spec = domain_spec(nx, ny, 2);
  std::vector<double> raw(nx * ny);
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x)
      raw[static_cast<size_t>(y) * nx + x] = x + 100.0 * y;  // row 0 = y 0
  std::filesystem::create_directories(dir.file("maps"));
  erg::job::testing::write_h5_doubles(dir.file("maps/b.h5"), "/terrain/elev", nx, ny, raw);
  const Layer layer = layer_of(
      R"({"map": {"path": "maps/b.h5", "dataset": "/terrain/elev", "scale": 0.5, "offset": -3,
                     "seam_tolerance": 1}})");
  const auto f = whole(layer, spec, LayerKind::kBedrock, dir.str());
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x)
      ASSERT_DOUBLE_EQ(at(f, spec, x, y), -3 + 0.5 * (x + 100.0 * y)) << x << "," << y;
  const TileGeom t = sub_tile(spec, 13, 7, 20, 15);
  const auto g = generate_layer(layer, LayerKind::kBedrock, spec, t, dir.str());
  for (int y = 0; y < t.ny; ++y)
    for (int x = 0; x < t.nx; ++x)
      ASSERT_DOUBLE_EQ(g[static_cast<size_t>(y) * t.nx + x],
                       -3 + 0.5 * ((13 + x) + 100.0 * (7 + y)));
  // Default dataset "/data"; explicit format with an unrelated extension.
  erg::job::testing::write_h5_doubles(dir.file("plain.dat"), "/data", nx, ny, raw);
  const auto h =
      whole(layer_of(R"({"map": {"path": "plain.dat", "format": "HDF5", "seam_tolerance": 1}})"),
            spec, LayerKind::kBedrock, dir.str());
  EXPECT_EQ(h, raw);
}

// Raw 16-bit samples of the test image: a value that names its cell.
std::uint16_t sample(int x, int y) {
  return static_cast<std::uint16_t>(1000 + x + 50 * y);
}

// The image of sample(): first image row = north edge (y = ny - 1).
std::vector<std::uint16_t> png_rows(int nx, int ny) {
  std::vector<std::uint16_t> rows(static_cast<size_t>(nx) * ny);
  for (int r = 0; r < ny; ++r)
    for (int x = 0; x < nx; ++x) rows[static_cast<size_t>(r) * nx + x] = sample(x, ny - 1 - r);
  return rows;
}

TEST(Maps, Png16NorthUpWithOffsetScaleAndSubTiles) {
  TempDir dir;
  const int nx = 40, ny = 30;
  const JobSpec spec = domain_spec(nx, ny, 1);
  erg::job::testing::write_png16_raw(dir.file("h.png"), nx, ny, png_rows(nx, ny));
  // value = offset + scale * raw / 65535 = sample - 1000 = x + 50 y.
  const Layer layer = layer_of(
      R"({"map": {"path": "h.png", "scale": 65535, "offset": -1000, "seam_tolerance": 1}})");
  const auto f = whole(layer, spec, LayerKind::kSand, dir.str());
  for (int y = 0; y < ny; ++y)
    for (int x = 0; x < nx; ++x)
      ASSERT_NEAR(at(f, spec, x, y), x + 50.0 * y, 1e-8) << x << "," << y;
  // South-west corner (0, 0) is the first sample of the last image row.
  EXPECT_NEAR(at(f, spec, 0, 0), 0, 1e-8);
  EXPECT_NEAR(at(f, spec, 0, ny - 1), 50.0 * (ny - 1), 1e-8);
  const TileGeom t = sub_tile(spec, 25, 11, 15, 19);
  const auto g = generate_layer(layer, LayerKind::kSand, spec, t, dir.str());
  for (int y = 0; y < t.ny; ++y)
    for (int x = 0; x < t.nx; ++x)
      ASSERT_NEAR(g[static_cast<size_t>(y) * t.nx + x], (25 + x) + 50.0 * (11 + y), 1e-8);
}

TEST(Maps, Png16FormatIsFoundWhateverTheCaseOfTheExtension) {
  TempDir dir;
  const int nx = 16, ny = 12;
  const JobSpec spec = domain_spec(nx, ny, 1);
  erg::job::testing::write_png16_raw(dir.file("H.PNG"), nx, ny, png_rows(nx, ny));
  erg::job::testing::write_png16_raw(dir.file("h.img"), nx, ny, png_rows(nx, ny));
  // validate() accepts an upper-case .PNG as a PNG; the generator must agree.
  JobSpec job = spec;
  *job.mutable_layers()->mutable_sand() =
      layer_of(R"({"map": {"path": "H.PNG", "scale": 65535, "seam_tolerance": 1}})");
  ASSERT_TRUE(erg::job::validate(job, dir.str()).empty())
      << erg::job::testing::join(erg::job::validate(job, dir.str()));
  for (const char* json :
       {R"({"map": {"path": "H.PNG", "scale": 65535, "seam_tolerance": 1}})",
        R"({"map": {"path": "h.img", "format": "PNG16", "scale": 65535, "seam_tolerance": 1}})"}) {
    std::vector<double> f;
    ASSERT_NO_THROW(f = whole(layer_of(json), spec, LayerKind::kSand, dir.str())) << json;
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) ASSERT_NEAR(at(f, spec, x, y), sample(x, y), 1e-8) << json;
  }
}

TEST(Maps, WrongSizeIsAnError) {
  TempDir dir;
  const JobSpec spec = domain_spec(40, 30, 1);
  erg::job::testing::write_png16_raw(dir.file("small.png"), 30, 40, png_rows(30, 40));
  EXPECT_THROW(
      whole(layer_of(R"({"map": {"path": "small.png"}})"), spec, LayerKind::kSand, dir.str()),
      std::runtime_error);
}

}  // namespace
}  // namespace erg::init
