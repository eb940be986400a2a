// SPDX-License-Identifier: Apache-2.0
// Validation: every bad spec is rejected with a message that names the field
// (as a path), the bad value and what is allowed; parse errors name the field;
// a valid spec has no problem; load_job_file names the file.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "job/spec.h"
#include "job_test_util.h"

namespace erg::job {
namespace {

using testing::join;
using testing::kMinimalJob;
using testing::parse_with_defaults;
using testing::TempDir;

// Success when one problem line contains every one of `parts`.
::testing::AssertionResult HasProblem(const std::vector<std::string>& problems,
                                      const std::vector<std::string>& parts) {
  for (const auto& p : problems) {
    bool all = true;
    for (const auto& part : parts) all = all && p.find(part) != std::string::npos;
    if (all) return ::testing::AssertionSuccess();
  }
  std::string want;
  for (const auto& part : parts) want += " [" + part + "]";
  return ::testing::AssertionFailure()
         << "no problem line contains all of" << want << "; problems:\n"
         << (problems.empty() ? "(none)\n" : join(problems));
}

// ---- one bad field (or pair of fields) at a time -----------------------------

struct BadSpec {
  std::string name;
  std::string json;                    // job text; kMinimalJob when empty
  std::function<void(JobSpec&)> edit;  // applied after the defaults
  std::vector<std::string> expect;     // all in one problem line
};

void PrintTo(const BadSpec& c, std::ostream* os) {
  *os << c.name;
}

class RejectsBadSpec : public ::testing::TestWithParam<BadSpec> {};

TEST_P(RejectsBadSpec, NamesFieldValueAndRange) {
  const BadSpec& c = GetParam();
  JobSpec spec = parse_with_defaults(c.json.empty() ? kMinimalJob : c.json);
  if (c.edit) c.edit(spec);
  const auto problems = validate(spec);
  ASSERT_FALSE(problems.empty()) << c.name << " was accepted";
  EXPECT_TRUE(HasProblem(problems, c.expect));
}

const char* kDomain = R"("domain": {"nx": 64, "ny": 48, "cell_size_m": 1})";

std::string job(const std::string& rest) {
  return std::string("{") + kDomain + ", " + rest + "}";
}

using erg::v1::Pile;

const std::vector<BadSpec> kBadSpecs = {
    {"NegativeNx",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_nx(-5); },
     {"domain.nx = -5 is out of range; allowed [8, 1048576] cells"}},
    {"ZeroNx",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_nx(0); },
     {"domain.nx = 0 is out of range; allowed [8, 1048576] cells"}},
    {"ZeroNy",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_ny(0); },
     {"domain.ny = 0 is out of range; allowed [8, 1048576] cells"}},
    {"HugeNy",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_ny(2000000); },
     {"domain.ny = 2000000 is out of range; allowed [8, 1048576] cells"}},
    {"ZeroCellSize",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_cell_size_m(0); },
     {"domain.cell_size_m = 0 is out of range; allowed [0.01, 1000] m"}},
    {"NegativeCellSize",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_cell_size_m(-2.5); },
     {"domain.cell_size_m = -2.5 is out of range; allowed [0.01, 1000] m"}},
    // A subnormal value must be reported, not crash the formatting of the message.
    {"SubnormalCellSize",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_cell_size_m(1e-310); },
     {"domain.cell_size_m = 1e-310 is out of range", "[0.01, 1000] m"}},
    {"MissingNx",
     R"({"domain": {"ny": 48, "cell_size_m": 1}, "wind": {"constant": {"speed_mps": 1}}})",
     nullptr,
     {"domain.nx is required", "allowed [8, 1048576] cells"}},
    {"MissingCellSize",
     R"({"domain": {"nx": 64, "ny": 48}, "wind": {"constant": {"speed_mps": 1}}})",
     nullptr,
     {"domain.cell_size_m is required", "allowed [0.01, 1000] m"}},
    {"MissingDomainNy",
     R"({"wind": {"constant": {"speed_mps": 1}}})",
     nullptr,
     {"domain.ny is required", "allowed [8, 1048576] cells"}},
    {"NaNCellSize",
     R"({"domain": {"nx": 64, "ny": 48, "cell_size_m": "NaN"}, "wind": {"constant": {"speed_mps": 1}}})",
     nullptr,
     {"domain.cell_size_m = nan is out of range; allowed [0.01, 1000] m"}},
    {"InfiniteVenturi",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "model": {"venturi_k": "Infinity"})"),
     nullptr,
     {"model.venturi_k = inf is out of range; allowed [0, 1] 1/m"}},
    {"NegInfiniteWindSpeed",
     job(R"("wind": {"constant": {"speed_mps": "-Infinity"}})"),
     nullptr,
     {"wind.constant.speed_mps = -inf is out of range; allowed [0, 100] m/s"}},
    {"NaNProbability",
     job(R"("wind": {"rose": {"entries": [{"direction_deg": 0, "speed_mps": 5, "probability": "NaN"}]}})"),
     nullptr,
     {"wind.rose.entries[0].probability = nan is out of range; allowed [0, 1]"}},
    {"HopTooLong",
     "",
     [](JobSpec& s) { s.mutable_model()->set_max_hop_m(20); },
     {"model.max_hop_m = 20", "domain.cell_size_m = 1", "16 cells", "max_hop_m <= 16 m"}},
    {"HopTooLongForSmallCells",
     "",
     [](JobSpec& s) { s.mutable_domain()->set_cell_size_m(0.25); },  // 8 m default > 4 m
     {"model.max_hop_m = 8", "32 cells", "domain.cell_size_m = 0.25", "max_hop_m <= 4 m"}},
    {"ShadowTooLong",
     "",
     [](JobSpec& s) { s.mutable_model()->set_shadow_radius_m(200); },
     {"model.shadow_radius_m = 200", "allowed shadow_radius_m <= 128 m"}},
    {"ShadowAngleMinAboveMax",
     "",
     [](JobSpec& s) {
       s.mutable_model()->set_shadow_angle_min_deg(20);
       s.mutable_model()->set_shadow_angle_max_deg(12);
     },
     {"model.shadow_angle_min_deg = 20", "model.shadow_angle_max_deg = 12"}},
    {"ShadowAngleMinEqualsMax",
     "",
     [](JobSpec& s) {
       s.mutable_model()->set_shadow_angle_min_deg(15);
       s.mutable_model()->set_shadow_angle_max_deg(15);
     },
     {"model.shadow_angle_min_deg = 15", "must be below", "model.shadow_angle_max_deg = 15"}},
    {"ShadowAngleTooSteep",
     "",
     [](JobSpec& s) { s.mutable_model()->set_shadow_angle_max_deg(90); },
     {"model.shadow_angle_max_deg = 90 is out of range; allowed [0, 89] deg"}},
    {"ReposeAbove89",
     "",
     [](JobSpec& s) { s.mutable_model()->set_repose_deg(95); },
     {"model.repose_deg = 95 is out of range; allowed [1, 89] deg"}},
    {"KcZeroExclusive",
     "",
     [](JobSpec& s) { s.mutable_model()->set_avalanche_kc(0); },
     {"model.avalanche_kc = 0 is out of range; allowed (0, 1]"}},
    {"NegativeSteps",
     "",
     [](JobSpec& s) { s.mutable_run()->set_steps(-1); },
     {"run.steps = -1 is out of range; allowed [0, 1000000000] steps"}},
    {"NegativeSeed",
     "",
     [](JobSpec& s) { s.set_seed(-7); },
     {"seed = -7 is out of range; allowed [0, 9007199254740992]"}},
    {"EmptyRose",
     job(R"("wind": {"rose": {}})"),
     nullptr,
     {"wind.rose.entries is empty", "at least one entry"}},
    {"RoseSumBelowOne",
     job(R"("wind": {"rose": {"entries": [{"direction_deg": 0, "speed_mps": 5, "probability": 0.5},
                                            {"direction_deg": 90, "speed_mps": 5, "probability": 0.4}]}})"),
     nullptr,
     {"wind.rose.entries[*].probability sum to 0.9", "must sum to 1"}},
    {"RoseProbabilityAboveOne",
     job(R"("wind": {"rose": {"entries": [{"direction_deg": 0, "speed_mps": 5, "probability": -0.5},
                                            {"direction_deg": 90, "speed_mps": 5, "probability": 1.5}]}})"),
     nullptr,
     {"wind.rose.entries[1].probability = 1.5 is out of range; allowed [0, 1]"}},
    {"RoseProbabilityNegative",
     job(R"("wind": {"rose": {"entries": [{"direction_deg": 0, "speed_mps": 5, "probability": -0.5},
                                            {"direction_deg": 90, "speed_mps": 5, "probability": 1.5}]}})"),
     nullptr,
     {"wind.rose.entries[0].probability = -0.5 is out of range; allowed [0, 1]"}},
    {"RoseEntryMissingSpeed",
     job(R"("wind": {"rose": {"entries": [{"direction_deg": 0, "probability": 1}]}})"),
     nullptr,
     {"wind.rose.entries[0].speed_mps is required", "[0, 100] m/s"}},
    {"SeriesNotIncreasing",
     job(R"("wind": {"series": {"keyframes": [{"step": 0, "speed_mps": 1}, {"step": 10, "speed_mps": 2},
                                                {"step": 5, "speed_mps": 3}]}})"),
     nullptr,
     {"wind.series.keyframes[2].step = 5", "previous keyframe's step 10"}},
    {"SeriesRepeatedStep",
     job(R"("wind": {"series": {"keyframes": [{"step": 4, "speed_mps": 1}, {"step": 4, "speed_mps": 2}]}})"),
     nullptr,
     {"wind.series.keyframes[1].step = 4", "must be greater", "step 4"}},
    {"SeriesEmpty", job(R"("wind": {"series": {}})"), nullptr, {"wind.series.keyframes is empty"}},
    {"SeriesPeriodTooShort",
     job(R"("wind": {"series": {"keyframes": [{"step": 0, "speed_mps": 1}, {"step": 30, "speed_mps": 2}],
                                "period_steps": 30}})"),
     nullptr,
     {"wind.series.period_steps = 30", "last keyframe's step 30"}},
    {"MissingWind",
     R"({"domain": {"nx": 64, "ny": 48, "cell_size_m": 1}})",
     nullptr,
     {"wind is required"}},
    {"WindWithoutRegime",
     job(R"("wind": {})"),
     nullptr,
     {"wind has no regime", "constant, rose, series, bidirectional"}},
    {"BidirectionalAngleTooWide",
     job(R"("wind": {"bidirectional": {"speed_mps": 5, "angle_deg": 200}})"),
     nullptr,
     {"wind.bidirectional.angle_deg = 200 is out of range; allowed [0, 180] deg"}},
    {"EventWithoutAction",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 3}])"),
     nullptr,
     {"events[0] has no action", "sand, bedrock, vegetation, wind"}},
    {"ObstacleWithoutShape",
     job(R"("wind": {"constant": {"speed_mps": 1}},
            "layers": {"obstacles": {"shapes": [{"height_m": 2}]}})"),
     nullptr,
     {"layers.obstacles.shapes[0] has no shape", "disk, rect, road"}},
    {"ObstacleRoadOfOnePoint",
     job(R"("wind": {"constant": {"speed_mps": 1}},
            "layers": {"obstacles": {"shapes": [{"road": {"points": [{"x_m": 1, "y_m": 2}], "width_m": 3}}]}})"),
     nullptr,
     {"layers.obstacles.shapes[0].road.points has 1 points", "at least 2"}},
    {"ObstacleOfZeroHeight",
     job(R"("wind": {"constant": {"speed_mps": 1}},
            "layers": {"obstacles": {"shapes": [{"height_m": 0, "disk": {"x_m": 1, "y_m": 2, "radius_m": 3}}]}})"),
     nullptr,
     {"layers.obstacles.shapes[0].height_m = 0 is out of range; allowed (0, 10000] m"}},
    {"ObstacleMapMissing",
     job(R"("wind": {"constant": {"speed_mps": 1}},
            "layers": {"obstacles": {"map": {"path": "no-such-obstacles.h5"}}})"),
     nullptr,
     {"layers.obstacles.map.path = \"no-such-obstacles.h5\": file not found"}},
    {"AddObstacleEventWithoutShape",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 3, "add_obstacle": {}}])"),
     nullptr,
     {"events[0].add_obstacle has no shape"}},
    // The wind warping's coarse cell: 4 cells at 1 m and the default radii
    // (sigma_min / 4 = 6.25 m), 16 at 0.25 m.
    {"DomainNotAMultipleOfTheCoarseWindCell",
     R"({"domain": {"nx": 66, "ny": 48, "cell_size_m": 1}, "wind": {"constant": {"speed_mps": 1}}})",
     nullptr,
     {"domain.nx = 66 is not a multiple of the wind-warping coarse cell, 4 cells",
      "allowed domain.nx = multiples of 4, e.g. 64 or 68"}},
    {"FineCellsMakeTheCoarseWindCellWider",
     R"({"domain": {"nx": 64, "ny": 40, "cell_size_m": 0.25}, "wind": {"constant": {"speed_mps": 1}}})",
     nullptr,
     {"domain.ny = 40 is not a multiple of the wind-warping coarse cell, 16 cells",
      "e.g. 32 or 48"}},
    {"EchoReachBeyondTheHalo",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "model": {"echo_dunes": true, "echo_reach_m": 200})"),
     nullptr,
     {"model.echo_reach_m = 200 m is 200 cells", "allowed echo_reach_m <= 128 m"}},
    {"EchoStickyInsideTheGap",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "model": {"echo_gap_ratio": 2, "echo_sticky_ratio": 1})"),
     nullptr,
     {"model.echo_sticky_ratio = 1 is below model.echo_gap_ratio = 2"}},
    {"EventWithoutStep",
     job(R"("wind": {"constant": {"speed_mps": 1}},
            "events": [{"sand": {"x_m": 1, "y_m": 2, "radius_m": 3, "height": 1}}])"),
     nullptr,
     {"events[0].step is required", "[0, 1000000000] steps"}},
    {"EventWindRoseEmpty",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 0, "sand":
            {"x_m": 1, "y_m": 2, "radius_m": 3, "height": 1}}, {"step": 9, "wind": {"rose": {}}}])"),
     nullptr,
     {"events[1].wind.rose.entries is empty"}},
    {"VegetationBothRectAndDisk",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 1, "vegetation":
            {"x_m": 1, "y_m": 2, "width_m": 3, "height_m": 4, "radius_m": 5, "density": 0.5}}])"),
     nullptr,
     {"events[0].vegetation must give either", "radius_m"}},
    {"VegetationNeitherRectNorDisk",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 1, "vegetation":
            {"x_m": 1, "y_m": 2, "density": 0.5}}])"),
     nullptr,
     {"events[0].vegetation must give either", "width_m and height_m"}},
    {"VegetationHalfRect",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 1, "vegetation":
            {"x_m": 1, "y_m": 2, "width_m": 3, "density": 0.5}}])"),
     nullptr,
     {"events[0].vegetation rectangle needs both width_m and height_m"}},
    {"VegetationDensityAboveOne",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 1, "vegetation":
            {"x_m": 1, "y_m": 2, "radius_m": 3, "density": 1.25}}])"),
     nullptr,
     {"events[0].vegetation.density = 1.25 is out of range; allowed [0, 1]"}},
    {"SandBrushFalloffAboveRadius",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 2, "sand":
            {"x_m": 1, "y_m": 2, "radius_m": 5, "falloff_m": 6, "height": 1}}])"),
     nullptr,
     {"events[0].sand.falloff_m = 6 exceeds radius_m = 5", "allowed [0, radius_m]"}},
    {"BedrockBrushFalloffAboveRadius",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 2, "bedrock":
            {"x_m": 1, "y_m": 2, "radius_m": 2.5, "falloff_m": 3.5, "height": -1}}])"),
     nullptr,
     {"events[0].bedrock.falloff_m = 3.5 exceeds radius_m = 2.5"}},
    {"UniformMinAboveMax",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"sand": {"uniform": {"min": 3, "max": 2}}})"),
     nullptr,
     {"layers.sand.uniform.min = 3 exceeds max = 2", "min <= max"}},
    {"UniformDefaultMaxBelowMin",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"bedrock": {"uniform": {"min": 1.5}}})"),
     nullptr,
     {"layers.bedrock.uniform.min = 1.5 exceeds max = 1"}},
    {"PileRadiusZero",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"sand": {"piles": [
            {"x_m": 1, "y_m": 1, "height": 1, "radius_m": 4}, {"x_m": 1, "y_m": 1, "height": 1, "radius_m": 0}]}})"),
     nullptr,
     {"layers.sand.piles[1].radius_m = 0 is out of range; allowed (0, 10000000] m"}},
    {"PatchesWithoutCoverage",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"sand": {"patches": {"radius_m": 4}}})"),
     nullptr,
     {"layers.sand.patches.coverage is required", "[0, 0.99]"}},
    {"FbmTooManyOctaves",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"bedrock": {"fbm": {"octaves": 17}}})"),
     nullptr,
     {"layers.bedrock.fbm.octaves = 17 is out of range; allowed [1, 16]"}},
    {"MapWithoutPath",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"vegetation": {"map": {"scale": 2}}})"),
     nullptr,
     {"layers.vegetation.map.path is empty"}},
    // Found by tests/fuzz: JSON may give an enum as a number, and proto3 keeps
    // a number it has no name for; the spec was accepted.
    {"UnknownTransportNumber",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "transport": 7)"),
     nullptr,
     {"transport = 7 is not a known value; allowed EXPECTED, STOCHASTIC"}},
    {"UnknownPileShapeNumber",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"sand": {"piles": [
            {"x_m": 1, "y_m": 1, "height": 1, "radius_m": 4, "shape": -3}]}})"),
     nullptr,
     {"layers.sand.piles[0].shape = -3 is not a known value", "CONE, GAUSSIAN, CYLINDER"}},
    // Local wind primitives [P19 4.4].
    {"WindPrimitiveWithoutKind",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [{"name": "a"}])"),
     nullptr,
     {"wind_primitives[0] has no kind", "vortex, turbulence"}},
    {"VortexWithoutPeakSpeed",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [
            {"vortex": {"x_m": 10, "y_m": 10, "radius_m": 5}}])"),
     nullptr,
     {"wind_primitives[0].vortex.peak_speed_mps is required", "[0, 100] m/s"}},
    {"VortexTooLargeForTheDomain",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [
            {"vortex": {"x_m": 10, "y_m": 10, "radius_m": 15, "peak_speed_mps": 3}}])"),
     nullptr,
     {"wind_primitives[0].vortex.radius_m = 15 m is out of range", "allowed [2, 14.4] m"}},
    {"VortexUnknownRotationNumber",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [
            {"vortex": {"x_m": 1, "y_m": 1, "radius_m": 5, "peak_speed_mps": 3, "rotation": 4}}])"),
     nullptr,
     {"wind_primitives[0].vortex.rotation = 4 is not a known value",
      "COUNTERCLOCKWISE, CLOCKWISE"}},
    {"WindPrimitiveEndBeforeStart",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [{"start_step": 10,
            "end_step": 10, "turbulence": {"amplitude_mps": 1}}])"),
     nullptr,
     {"wind_primitives[0].end_step = 10 must be greater than start_step = 10"}},
    {"WindPrimitiveRampTooLong",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [{"start_step": 10,
            "end_step": 20, "ramp_steps": 6, "turbulence": {"amplitude_mps": 1}}])"),
     nullptr,
     {"wind_primitives[0].ramp_steps = 6 is more than half", "allowed [0, 5]"}},
    {"TurbulenceWavelengthUnderFourCells",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [{"step": 3, "wind_primitive":
            {"turbulence": {"amplitude_mps": 1, "wavelength_m": 3}}}])"),
     nullptr,
     {"events[0].wind_primitive.turbulence.wavelength_m = 3 m is under 4 cells"}},
    {"TurbulenceFalloffAboveRadius",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [
            {"turbulence": {"amplitude_mps": 1, "radius_m": 10, "falloff_m": 12}}])"),
     nullptr,
     {"wind_primitives[0].turbulence.falloff_m = 12 exceeds radius_m = 10"}},
    {"TurbulenceZeroFalloff",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [
            {"turbulence": {"amplitude_mps": 1, "radius_m": 10, "falloff_m": 0}}])"),
     nullptr,
     {"wind_primitives[0].turbulence.falloff_m = 0 is out of range", "(0, 10000000] m"}},
    {"RemoveUnknownWindPrimitive",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "wind_primitives": [{"name": "a",
            "turbulence": {"amplitude_mps": 1}}], "events": [{"step": 4, "remove_wind_primitive": "b"}])"),
     nullptr,
     {"events[0].remove_wind_primitive = \"b\" names no wind primitive"}},
    {"RemoveWindPrimitiveBeforeItIsAdded",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "events": [
            {"step": 4, "remove_wind_primitive": "v"},
            {"step": 5, "wind_primitive": {"name": "v", "turbulence": {"amplitude_mps": 1}}}])"),
     nullptr,
     {"events[0].remove_wind_primitive = \"v\" names no wind primitive"}},
    {"UnknownMapFormatNumber",
     job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {"sand": {"map": {"path": "m.h5", "format": 9}}})"),
     nullptr,
     {"layers.sand.map.format = 9 is not a known value; allowed HDF5, PNG16, GEOTIFF, EXR"}},
};

INSTANTIATE_TEST_SUITE_P(Validate, RejectsBadSpec, ::testing::ValuesIn(kBadSpecs),
                         [](const ::testing::TestParamInfo<BadSpec>& i) { return i.param.name; });

// ---- specs that are fine ------------------------------------------------------

TEST(Validate, MinimalSpecHasNoProblem) {
  const auto problems = validate(testing::minimal_spec());
  EXPECT_TRUE(problems.empty()) << join(problems);
}

TEST(Validate, RichSpecHasNoProblem) {
  const JobSpec spec = parse_with_defaults(R"({
    "name": "rich", "transport": "stochastic", "seed": 42,
    "domain": {"nx": 64, "ny": 48, "cell_size_m": 0.5},
    "layers": {
      "bedrock": {"constant": 2, "fbm": {"amplitude": 3, "ridged": true, "anisotropy": 4}},
      "sand": {"uniform": {"min": 0, "max": 0.5}, "patches": {"coverage": 0.3, "radius_m": 3},
               "piles": [{"x_m": 5, "y_m": 5, "height": 2, "radius_m": 3, "shape": "GAUSSIAN"}]},
      "vegetation": {"constant": 0.1}
    },
    "wind": {"rose": {"entries": [{"direction_deg": 0, "speed_mps": 5, "probability": 0.25},
                                   {"direction_deg": 90, "speed_mps": 6, "probability": 0.75}],
                       "hold_steps": 5, "sector_width_deg": 30}},
    "events": [
      {"step": 10, "sand": {"x_m": 1, "y_m": 1, "radius_m": 2, "falloff_m": 2, "height": 1}},
      {"step": 11, "bedrock": {"x_m": 1, "y_m": 1, "radius_m": 2, "height": -1}},
      {"step": 12, "vegetation": {"x_m": 1, "y_m": 1, "width_m": 5, "height_m": 0, "density": 1}},
      {"step": 13, "vegetation": {"x_m": 1, "y_m": 1, "radius_m": 5, "density": 0}},
      {"step": 14, "wind": {"series": {"keyframes": [{"step": 0, "speed_mps": 1},
                                                     {"step": 9, "speed_mps": 2}], "period_steps": 10}}},
      {"step": 15, "wind": {"bidirectional": {"speed_mps": 7, "angle_deg": 120, "flux_ratio": 3}}}
    ],
    "model": {"max_hop_m": 8, "shadow_radius_m": 64, "repose_deg": 34},
    "run": {"steps": 0, "snapshot_every": 0}
  })");
  const auto problems = validate(spec);
  EXPECT_TRUE(problems.empty()) << join(problems);
}

TEST(Validate, ProbabilitiesSummingToOneWithinToleranceAreAccepted) {
  JobSpec spec = parse_with_defaults(job(R"("wind": {"rose": {"entries": [
      {"direction_deg": 0, "speed_mps": 5, "probability": 0.1},
      {"direction_deg": 10, "speed_mps": 5, "probability": 0.2},
      {"direction_deg": 20, "speed_mps": 5, "probability": 0.7}]}})"));
  EXPECT_TRUE(validate(spec).empty()) << join(validate(spec));
}

TEST(Validate, HopOfExactlySixteenCellsIsAllowed) {
  JobSpec spec = testing::minimal_spec();
  spec.mutable_domain()->set_cell_size_m(0.5);
  spec.mutable_model()->set_max_hop_m(8);  // 16 cells
  EXPECT_TRUE(validate(spec).empty()) << join(validate(spec));
  spec.mutable_model()->set_max_hop_m(8.01);
  EXPECT_TRUE(HasProblem(validate(spec), {"model.max_hop_m = 8.01", "max_hop_m <= 8 m"}));
}

TEST(Validate, ReportsEveryRangeProblemAtOnce) {
  JobSpec spec = testing::minimal_spec();
  spec.mutable_domain()->set_nx(-5);
  spec.mutable_model()->set_repose_deg(95);
  spec.mutable_run()->set_steps(-3);
  const auto problems = validate(spec);
  EXPECT_EQ(problems.size(), 3u) << join(problems);
  EXPECT_TRUE(HasProblem(problems, {"domain.nx = -5"}));
  EXPECT_TRUE(HasProblem(problems, {"model.repose_deg = 95"}));
  EXPECT_TRUE(HasProblem(problems, {"run.steps = -3"}));
}

TEST(Validate, MissingDomainReportsAllThreeFields) {
  const auto problems =
      validate(parse_with_defaults(R"({"wind": {"constant": {"speed_mps": 1}}})"));
  EXPECT_TRUE(HasProblem(problems, {"domain.nx is required"}));
  EXPECT_TRUE(HasProblem(problems, {"domain.ny is required"}));
  EXPECT_TRUE(HasProblem(problems, {"domain.cell_size_m is required"}));
}

// ---- parse errors ---------------------------------------------------------------

std::string parse_error(const std::string& text, const std::string& origin = "jobs/a.json") {
  try {
    parse_json(text, origin);
  } catch (const SpecError& e) {
    EXPECT_EQ(e.problems().size(), 1u);
    return e.what();
  }
  return "(parsed)";
}

TEST(Parse, UnknownEnumNameNamesTheFieldAndValue) {
  const std::string e = parse_error(job(R"("transport": "fast")"));
  EXPECT_NE(e.find("jobs/a.json"), std::string::npos) << e;
  EXPECT_NE(e.find("transport"), std::string::npos) << e;
  EXPECT_NE(e.find("fast"), std::string::npos) << e;
}

TEST(Parse, UnknownNestedEnumNameNamesTheFieldPath) {
  const std::string e = parse_error(
      job(R"("layers": {"sand": {"piles": [{"x_m": 1, "y_m": 1, "height": 1, "radius_m": 1,
                                            "shape": "pyramid"}]}})"));
  EXPECT_NE(e.find("layers.sand.piles[0].shape"), std::string::npos) << e;
  EXPECT_NE(e.find("pyramid"), std::string::npos) << e;
}

TEST(Parse, EnumNamesAreCaseInsensitive) {
  EXPECT_EQ(parse_json(job(R"("transport": "stochastic")")).transport(), JobSpec::STOCHASTIC);
  EXPECT_EQ(parse_json(job(R"("transport": "Expected")")).transport(), JobSpec::EXPECTED);
}

TEST(Parse, UnknownFieldNamesTheField) {
  const std::string e = parse_error(R"({"domain": {"nx": 64, "nyy": 48, "cell_size_m": 1}})");
  EXPECT_NE(e.find("jobs/a.json"), std::string::npos) << e;
  EXPECT_NE(e.find("nyy"), std::string::npos) << e;
  EXPECT_NE(e.find("domain"), std::string::npos) << e;
  const std::string top = parse_error(job(R"("wnd": {})"));
  EXPECT_NE(top.find("wnd"), std::string::npos) << top;
}

TEST(Parse, WrongJsonTypeNamesTheField) {
  std::string e = parse_error(R"({"domain": {"nx": "abc", "ny": 48, "cell_size_m": 1}})");
  EXPECT_NE(e.find("domain.nx"), std::string::npos) << e;
  EXPECT_NE(e.find("abc"), std::string::npos) << e;
  e = parse_error(R"({"domain": {"nx": 1.5, "ny": 48, "cell_size_m": 1}})");
  EXPECT_NE(e.find("domain.nx"), std::string::npos) << e;
  e = parse_error(R"({"domain": 5})");
  EXPECT_NE(e.find("domain"), std::string::npos) << e;
  e = parse_error(job(R"("model": {"repose_deg": true})"));
  EXPECT_NE(e.find("model.repose_deg"), std::string::npos) << e;
}

TEST(Parse, SyntaxErrorNamesTheOrigin) {
  const std::string e = parse_error(R"({"domain": {"nx": 64,)", "broken.json");
  EXPECT_EQ(e.rfind("broken.json", 0), 0u) << e;
  EXPECT_NE(e.find("not a valid job spec"), std::string::npos) << e;
}

TEST(Parse, TwoWindRegimesAreRejected) {
  const std::string e =
      parse_error(job(R"("wind": {"constant": {"speed_mps": 1}, "rose": {"entries": []}})"));
  EXPECT_NE(e.find("wind"), std::string::npos) << e;
  EXPECT_NE(e.find("rose"), std::string::npos) << e;
}

TEST(Parse, AcceptsNaNAndInfinityStringsForDoubles) {
  const JobSpec s = parse_json(job(R"("model": {"venturi_k": "NaN", "slab_m": "-Infinity"})"));
  EXPECT_TRUE(std::isnan(s.model().venturi_k()));
  EXPECT_EQ(s.model().slab_m(), -std::numeric_limits<double>::infinity());
}

// ---- map files -------------------------------------------------------------------

std::string map_job(const std::string& layer, const std::string& map) {
  return job(R"("wind": {"constant": {"speed_mps": 1}}, "layers": {")" + layer + R"(": {"map": )" +
             map + "}}");
}

TEST(ValidateMaps, MissingFileNamesFieldAndFile) {
  TempDir dir;
  const auto problems =
      validate(parse_with_defaults(map_job("sand", R"({"path": "maps/none.h5"})")), dir.str());
  EXPECT_TRUE(HasProblem(
      problems, {"layers.sand.map.path", "maps/none.h5", "not found", dir.file("maps/none.h5")}));
}

TEST(ValidateMaps, Hdf5OfWrongShapeNamesBothSizes) {
  TempDir dir;
  testing::write_h5_doubles(dir.file("small.h5"), "/data", 10, 12, std::vector<double>(120, 1.0));
  const auto problems =
      validate(parse_with_defaults(map_job("bedrock", R"({"path": "small.h5"})")), dir.str());
  EXPECT_TRUE(HasProblem(problems, {"layers.bedrock.map.path", "small.h5", "10 x 12", "64 x 48"}));
}

TEST(ValidateMaps, Hdf5OfRightShapeIsAccepted) {
  TempDir dir;
  testing::write_h5_doubles(dir.file("ok.h5"), "/elev/m", 64, 48,
                            std::vector<double>(64 * 48, 1.0));
  const auto problems = validate(
      parse_with_defaults(map_job("bedrock", R"({"path": "ok.h5", "dataset": "/elev/m"})")),
      dir.str());
  EXPECT_TRUE(problems.empty()) << join(problems);
  // The same file with a dataset that does not exist.
  const auto bad =
      validate(parse_with_defaults(map_job("bedrock", R"({"path": "ok.h5", "dataset": "/nope"})")),
               dir.str());
  EXPECT_TRUE(HasProblem(bad, {"layers.bedrock.map.path", "ok.h5", "cannot be read"}));
}

TEST(ValidateMaps, Png16OfWrongShapeNamesBothSizes) {
  TempDir dir;
  testing::write_png16_raw(dir.file("wide.png"), 48, 64, std::vector<std::uint16_t>(48 * 64, 7));
  const auto problems =
      validate(parse_with_defaults(map_job("vegetation", R"({"path": "wide.png"})")), dir.str());
  EXPECT_TRUE(
      HasProblem(problems, {"layers.vegetation.map.path", "wide.png", "48 x 64", "64 x 48"}));
}

TEST(ValidateMaps, Png16OfRightShapeIsAccepted) {
  TempDir dir;
  testing::write_png16_raw(dir.file("ok.png"), 64, 48, std::vector<std::uint16_t>(64 * 48, 7));
  const auto problems =
      validate(parse_with_defaults(map_job("vegetation", R"({"path": "ok.png"})")), dir.str());
  EXPECT_TRUE(problems.empty()) << join(problems);
}

TEST(ValidateMaps, UnknownExtensionAsksForAFormat) {
  TempDir dir;
  testing::write_text(dir.file("m.dat"), "x");
  const auto problems =
      validate(parse_with_defaults(map_job("resistance", R"({"path": "m.dat"})")), dir.str());
  EXPECT_TRUE(HasProblem(problems, {"layers.resistance.map.format", "m.dat"}));
}

// Found by tests/fuzz: a path too long for the file system made validate()
// throw std::filesystem::filesystem_error (erg check died in std::terminate).
TEST(ValidateMaps, PathTooLongIsAProblemNotAnException) {
  TempDir dir;
  const std::string long_name(5000, 'a');
  const std::string long_part(300, 'b');  // one component over NAME_MAX
  for (const std::string& path : {long_name + ".h5", long_part + "/m.h5", "/" + long_part}) {
    std::vector<std::string> problems;
    ASSERT_NO_THROW(
        problems = validate(parse_with_defaults(map_job("sand", R"({"path": ")" + path + R"("})")),
                            dir.str()))
        << path.size() << " characters";
    EXPECT_TRUE(HasProblem(problems, {"layers.sand.map.path"})) << join(problems);
  }
}

// A map must be a regular file: a directory is reported, and a FIFO or a
// device (which would block or never end) is never opened.
TEST(ValidateMaps, DirectoriesAndDevicesAreNotRead) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("maps.h5"));
  EXPECT_TRUE(HasProblem(
      validate(parse_with_defaults(map_job("sand", R"({"path": "maps.h5"})")), dir.str()),
      {"layers.sand.map.path", "maps.h5", "not a regular file"}));
  ASSERT_EQ(::mkfifo(dir.file("fifo.png").c_str(), 0600), 0);
  EXPECT_TRUE(HasProblem(
      validate(parse_with_defaults(map_job("sand", R"({"path": "fifo.png"})")), dir.str()),
      {"layers.sand.map.path", "fifo.png", "not a regular file"}));
  EXPECT_TRUE(HasProblem(
      validate(parse_with_defaults(map_job("sand", R"({"path": "/dev/zero", "format": "PNG16"})"))),
      {"layers.sand.map.path", "/dev/zero", "not a regular file"}));
}

// A path "a", NUL, ".h5" would have been opened as "a" by the C libraries.
TEST(ValidateMaps, PathWithNulIsRejected) {
  TempDir dir;
  testing::write_h5_doubles(dir.file("a"), "/data", 64, 48, std::vector<double>(64 * 48, 1.0));
  EXPECT_TRUE(HasProblem(
      validate(parse_with_defaults(map_job("sand", R"({"path": "a\u0000.h5"})")), dir.str()),
      {"layers.sand.map.path contains a NUL character"}));
}

// ---- load_job_file ---------------------------------------------------------------

TEST(LoadJobFile, LoadsAValidFileWithDefaults) {
  TempDir dir;
  testing::write_text(dir.file("ok.json"), kMinimalJob);
  const JobSpec spec = load_job_file(dir.file("ok.json"));
  EXPECT_EQ(spec.domain().nx(), 64);
  EXPECT_EQ(spec.model().repose_deg(), 33);
}

TEST(LoadJobFile, ProblemsNameTheFile) {
  TempDir dir;
  const std::string path = dir.file("bad_job.json");
  testing::write_text(path, R"({"domain": {"nx": -5, "ny": 48, "cell_size_m": 1},
                              "wind": {"constant": {"speed_mps": 1}}, "model": {"repose_deg": 95}})");
  try {
    load_job_file(path);
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    ASSERT_EQ(e.problems().size(), 2u) << e.what();
    for (const auto& p : e.problems()) EXPECT_EQ(p.rfind(path + ": ", 0), 0u) << p;
    EXPECT_TRUE(HasProblem(e.problems(), {path, "domain.nx = -5", "[8, 1048576] cells"}));
    EXPECT_TRUE(HasProblem(e.problems(), {path, "model.repose_deg = 95"}));
  }
}

TEST(LoadJobFile, ParseErrorNamesTheFile) {
  TempDir dir;
  const std::string path = dir.file("typo.json");
  testing::write_text(path, job(R"("transport": "fast")"));
  try {
    load_job_file(path);
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("transport"), std::string::npos) << e.what();
  }
}

TEST(LoadJobFile, MissingFileNamesTheFile) {
  TempDir dir;
  const std::string path = dir.file("absent.json");
  try {
    load_job_file(path);
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    // The system's reason, not only "cannot open".
    EXPECT_NE(std::string(e.what()).find("No such file or directory"), std::string::npos)
        << e.what();
  }
}

// Six different mistakes, one line each, in one pass: two unknown fields
// (one a typo, named with the field meant), an enum value not in the schema
// (with the allowed values, no type URL), two values out of range and a
// cross-field rule.
const char* kSixMistakes = R"({
  "transport": "STOCHASTICAL",
  "colour": "red",
  "domain": {"nx": -5, "ny": 64, "cell_size_m": 1},
  "run": {"steps": 100, "snapshot_evry": 10},
  "model": {"max_hop_m": 40},
  "wind": {"constant": {"speed_mps": 8, "direction_deg": 400}}
})";

TEST(LoadJobFile, EveryProblemInOnePass) {
  TempDir dir;
  const std::string path = dir.file("six.json");
  testing::write_text(path, kSixMistakes);
  try {
    load_job_file(path);
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    const auto& p = e.problems();
    ASSERT_EQ(p.size(), 6u) << e.what();
    EXPECT_TRUE(HasProblem(p, {path + ": colour: unknown field; allowed name, domain"}));
    EXPECT_TRUE(HasProblem(p, {"run.snapshot_evry: unknown field; did you mean 'snapshot_every'"}));
    EXPECT_TRUE(HasProblem(
        p, {"transport = \"STOCHASTICAL\" is not a known value; allowed EXPECTED, STOCHASTIC"}));
    EXPECT_TRUE(HasProblem(p, {"domain.nx = -5 is out of range; allowed [8, 1048576] cells"}));
    EXPECT_TRUE(HasProblem(p, {"wind.constant.direction_deg = 400 is out of range"}));
    EXPECT_TRUE(HasProblem(p, {"model.max_hop_m = 40 m", "at most 16 cells"}));
    for (const auto& line : p) EXPECT_EQ(line.find("type.googleapis.com"), std::string::npos);
  }
}

TEST(LoadJobFile, WrongTypesAreNamedOnceEach) {
  TempDir dir;
  const std::string path = dir.file("types.json");
  testing::write_text(path, R"({"domain": {"nx": "many", "ny": 48.5, "cell_size_m": 1},
                              "wind": {"constant": {"speed_mps": true}}, "name": 3})");
  try {
    load_job_file(path);
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    const auto& p = e.problems();
    ASSERT_EQ(p.size(), 4u) << e.what();  // not again as "required"
    EXPECT_TRUE(HasProblem(p, {"domain.nx = \"many\" is not a whole number; allowed [8"}));
    EXPECT_TRUE(HasProblem(p, {"domain.ny = 48.5 is not a whole number"}));
    EXPECT_TRUE(HasProblem(p, {"wind.constant.speed_mps = true is not a number"}));
    EXPECT_TRUE(HasProblem(p, {"name = 3 is not a string"}));
  }
}

TEST(ReadableJson, IntegersAreNumbersAndParseBack) {
  const JobSpec spec = parse_with_defaults(kMinimalJob);
  const std::string text = to_readable_json(spec);
  EXPECT_NE(text.find("\"nx\": 64"), std::string::npos) << text;
  EXPECT_NE(text.find("\"steps\": 1000"), std::string::npos) << text;
  EXPECT_EQ(text.find("\"nx\": \"64\""), std::string::npos) << text;
  const JobSpec back = parse_json(text);
  EXPECT_EQ(back.SerializeAsString(), spec.SerializeAsString());
}

TEST(LoadJobFile, RelativeMapPathsAreResolvedAgainstTheJobDirectory) {
  TempDir dir;
  std::filesystem::create_directories(dir.file("jobs/maps"));
  testing::write_h5_doubles(dir.file("jobs/maps/b.h5"), "/data", 64, 48,
                            std::vector<double>(64 * 48, 0.5));
  testing::write_text(dir.file("jobs/j.json"), map_job("bedrock", R"({"path": "maps/b.h5"})"));
  EXPECT_NO_THROW(load_job_file(dir.file("jobs/j.json")));
  EXPECT_EQ(base_dir_of(dir.file("jobs/j.json")), dir.file("jobs"));
  EXPECT_EQ(base_dir_of("j.json"), ".");
  EXPECT_EQ(resolve_path("maps/b.h5", "/x/jobs"), "/x/jobs/maps/b.h5");
  EXPECT_EQ(resolve_path("/abs/b.h5", "/x/jobs"), "/abs/b.h5");
  // Moved next to a job elsewhere, the same relative path is missing.
  testing::write_text(dir.file("j2.json"), map_job("bedrock", R"({"path": "maps/b.h5"})"));
  try {
    load_job_file(dir.file("j2.json"));
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    EXPECT_TRUE(HasProblem(
        e.problems(), {dir.file("j2.json"), "layers.bedrock.map.path", "maps/b.h5", "not found"}));
  }
}

}  // namespace
}  // namespace erg::job
