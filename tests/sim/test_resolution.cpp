// SPDX-License-Identifier: Apache-2.0
// The lengths the model uses against the grid (sim/resolution.h): a job
// whose cells are too coarse for a length is warned, naming the length, its
// value, the cell size and what follows; a fine job is not; and the cell size
// each warning gives as resolving the length does resolve it.
#include <gtest/gtest.h>

#include <string>

#include "job/spec.h"
#include "sim/resolution.h"
#include "wind/regime.h"

namespace erg {
namespace {

erg::v1::JobSpec job(double cell_m, const std::string& wind, const std::string& extra = "") {
  erg::v1::JobSpec s = job::parse_json(R"({"domain": {"nx": 64, "ny": 64, "cell_size_m": )" +
                                           std::to_string(cell_m) + "}, " + wind +
                                           (extra.empty() ? "" : ", " + extra) + "}",
                                       "test");
  job::apply_defaults(s);
  return s;
}
const std::string kModelWind = R"("wind": {"constant": {"speed_mps": 5}})";
const std::string kShearWind =
    R"("wind": {"constant": {"speed_mps": 0.4}, "speed_is": "SHEAR_VELOCITY"})";

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// The one length a valid job leaves unresolved (an empty one, and a
// failure, when there is not exactly one).
UnresolvedLength only_one(const erg::v1::JobSpec& spec) {
  EXPECT_TRUE(job::validate(spec).empty()) << job::validate(spec)[0];
  const auto u = unresolved_lengths(spec);
  EXPECT_EQ(u.size(), 1u);
  return u.size() == 1 ? u[0] : UnresolvedLength{};
}

TEST(Resolution, DefaultModelJobAtOneMetreIsResolved) {
  const auto spec = job(1.0, kModelWind);
  EXPECT_TRUE(job::validate(spec).empty());
  EXPECT_TRUE(unresolved_lengths(spec).empty());
}

// 0.6 x 1.19 m = 0.714 m, under one cell of 1 m: raised to the cell. (The
// step resolved, so that the hop's is the only warning.)
TEST(Resolution, SaturationLengthHopAtOneMetreIsWarned) {
  const auto spec = job(1.0, kShearWind, R"("model": {"slab_m": 0.025})");
  const UnresolvedLength u = only_one(spec);
  EXPECT_EQ(u.what, "saltation hop");
  EXPECT_NEAR(u.length_m, 0.6 * 2.2 * 2650.0 / 1.225 * 0.00025, 1e-9);
  EXPECT_DOUBLE_EQ(u.cell_m, 1.0);
  const std::string& w = u.warning;
  EXPECT_TRUE(has(w, "physics.saturation_length_m")) << w;
  EXPECT_TRUE(has(w, "0.714 m")) << w;
  EXPECT_TRUE(has(w, "2 cells of 1 m (domain.cell_size_m)")) << w;
  EXPECT_TRUE(has(w, "raised to 1 m (1 cell)")) << w;
  EXPECT_TRUE(has(w, "dune wavelength depend on the grid")) << w;
  EXPECT_TRUE(has(w, "resolved at domain.cell_size_m <= 0.357 m")) << w;
  EXPECT_EQ(resolution_warnings(spec), std::vector<std::string>{w});
}

// Under one cell and above max_hop_m: raised to max_hop_m, still under a
// cell (the continent-scale example's 10 m cells).
TEST(Resolution, HopRaisedOnlyToMaxHopIsSaidSo) {
  const auto u = unresolved_lengths(job(10.0, kShearWind));
  ASSERT_FALSE(u.empty());
  EXPECT_EQ(u[0].what, "saltation hop");
  EXPECT_TRUE(has(u[0].warning, "raised to 8 m (model.max_hop_m)")) << u[0].warning;
}

// Between one and two cells the hop is not raised, but still warned.
TEST(Resolution, HopBetweenOneAndTwoCellsIsWarnedNotRaised) {
  const auto u = only_one(job(1.0, kShearWind, R"("physics": {"saturation_length_m": 2.5})"));
  EXPECT_TRUE(has(u.warning, "= 1.5 m, is shorter than 2 cells")) << u.warning;
  EXPECT_FALSE(has(u.warning, "raised")) << u.warning;
}

TEST(Resolution, SaturationLengthHopOnFineCellsIsResolved) {
  const auto spec = job(0.25, kShearWind, R"("model": {"max_hop_m": 4})");
  ASSERT_TRUE(job::validate(spec).empty());
  EXPECT_TRUE(unresolved_lengths(spec).empty()) << resolution_warnings(spec)[0];
}

// 4 m cells: the 10 m shadow is 3 whole cells (12 m); the 8 m hop is 2
// cells, resolved.
TEST(Resolution, ShadowOnCoarseCellsIsWarned) {
  const auto u = only_one(job(4.0, kModelWind));
  EXPECT_EQ(u.field, "model.shadow_radius_m");
  EXPECT_TRUE(has(u.warning, "model.shadow_radius_m = 10 m, is shorter than 4 cells")) << u.warning;
  EXPECT_TRUE(has(u.warning, "3 whole cells (12 m, 20% longer)")) << u.warning;
  EXPECT_DOUBLE_EQ(u.finest_m, 2.5);
}

TEST(Resolution, ShortModelHopIsWarned) {
  const auto u = only_one(job(1.0, kModelWind, R"("model": {"max_hop_m": 1.5})"));
  EXPECT_EQ(u.what, "longest saltation hop");
  EXPECT_TRUE(has(u.warning, "model.max_hop_m = 1.5 m")) << u.warning;
}

// 10 m cells: the small smoothing's sigma of 25 m spans 2.5 cells.
TEST(Resolution, WarpingOnCoarseCellsIsWarned) {
  const auto u =
      only_one(job(10.0, kModelWind, R"("model": {"shadow_radius_m": 40, "max_hop_m": 20})"));
  EXPECT_EQ(u.field, "model.warp_small_radius_m");
  EXPECT_TRUE(has(u.warning, "2.5 cells per sigma at 10 m cells")) << u.warning;
}

TEST(Resolution, EchoReachIsCheckedOnlyWithEchoDunes) {
  const auto off = job(2.0, kModelWind, R"("model": {"echo_reach_m": 6})");
  EXPECT_TRUE(unresolved_lengths(off).empty());
  const auto on = job(2.0, kModelWind, R"("model": {"echo_reach_m": 6, "echo_dunes": true})");
  EXPECT_EQ(only_one(on).field, "model.echo_reach_m");
}

TEST(Resolution, ShearKernelOnCoarseCellsIsWarned) {
  const auto spec = job(
      30.0, kShearWind,
      R"("physics": {"shear_stress_a": 3}, "model": {"shadow_radius_m": 120, "max_hop_m": 60})");
  bool found = false;
  for (const auto& u : unresolved_lengths(spec))
    if (u.field == "physics.shear_stress_radius_m") {
      found = true;
      EXPECT_TRUE(has(u.warning, "4 whole cells (120 m, 20% longer)")) << u.warning;
    }
  EXPECT_TRUE(found);
}

// With the shear stress on (the physical modes' default), a step lifting
// more than 1/40 of the cell is warned, with the largest slab that is not;
// without the stress (A = 0, or model units) the step is not.
TEST(Resolution, StepIsWarnedOnlyWithTheShearStress) {
  const auto spec = job(1.0, kShearWind);  // slab_m 0.1, A = 4 by default
  const std::string w = step_warning(spec);
  EXPECT_TRUE(has(w, "model.slab_m = 0.1 m, is more than 1/40 of the cell")) << w;
  EXPECT_TRUE(has(w, "physics.shear_stress_a = 4")) << w;
  EXPECT_TRUE(has(w, "they stop at model.slab_m <= 0.025 m")) << w;
  const auto all = resolution_warnings(spec);
  ASSERT_FALSE(all.empty());
  EXPECT_EQ(all.back(), w);
  EXPECT_EQ(step_warning(job(1.0, kShearWind, R"("model": {"slab_m": 0.025})")), "");
  EXPECT_EQ(step_warning(job(0.5, kShearWind, R"("model": {"slab_m": 0.0125})")), "");
  EXPECT_NE(step_warning(job(0.5, kShearWind, R"("model": {"slab_m": 0.025})")), "");
  EXPECT_EQ(step_warning(job(4.0, kShearWind)), "");  // 0.1 m = 1/40 of 4 m
  EXPECT_EQ(step_warning(job(1.0, kShearWind, R"("physics": {"shear_stress_a": 0})")), "");
  EXPECT_EQ(step_warning(job(1.0, kModelWind)), "");
}

// A bidirectional period shorter than 1 + flux_ratio steps is warned, for
// the job's wind and for a wind switched in by an event, and what the warning
// says of the secondary wind is what wind/regime.cpp blows.
TEST(Resolution, BidirectionalPeriodTooShortForTheSecondaryIsWarned) {
  const auto bidi = [](int period, int ratio) {
    return R"({"bidirectional": {"speed_mps": 5, "angle_deg": 90, "flux_ratio": )" +
           std::to_string(ratio) + R"(, "period_steps": )" + std::to_string(period) + "}}";
  };
  // The one period warning of a valid job ("" and a failure otherwise).
  const auto only_warning = [](const erg::v1::JobSpec& spec) {
    EXPECT_TRUE(job::validate(spec).empty());
    const auto w = wind_period_warnings(spec);
    EXPECT_EQ(w.size(), 1u);
    return w.size() == 1 ? w[0] : std::string();
  };
  const auto spec = job(1.0, R"("wind": )" + bidi(10, 1000));
  const std::string w = only_warning(spec);
  EXPECT_TRUE(has(w,
                  "wind.bidirectional.period_steps = 10 is shorter than 1 + "
                  "wind.bidirectional.flux_ratio = 1001 steps"))
      << w;
  EXPECT_TRUE(has(w, "one step in about 1% of the periods")) << w;
  EXPECT_TRUE(has(w, "period_steps >= 1001 keeps both winds in every period")) << w;
  EXPECT_EQ(resolution_warnings(spec).back(), w);
  // What the wind does: over 1001 periods the secondary blows in 10 of
  // them, one step each (1%).
  int periods_with_secondary = 0, secondary_steps = 0;
  for (int k = 0; k < 1001; ++k) {
    int here = 0;
    for (int t = 0; t < 10; ++t) here += wind::regime_at(spec.wind(), 10 * k + t, 0, 1).x < 0.5;
    periods_with_secondary += here > 0;
    secondary_steps += here;
  }
  EXPECT_EQ(periods_with_secondary, 10);
  EXPECT_EQ(secondary_steps, 10);
  // From 1 + flux_ratio steps on the secondary has a step in every period.
  EXPECT_TRUE(wind_period_warnings(job(1.0, R"("wind": )" + bidi(3, 2))).empty());
  EXPECT_TRUE(wind_period_warnings(job(1.0, R"("wind": )" + bidi(20, 5))).empty());
  EXPECT_EQ(wind_period_warnings(job(1.0, R"("wind": )" + bidi(2, 2))).size(), 1u);
  // A wind switched in by the timeline is named by its event.
  const std::string we =
      only_warning(job(1.0, kModelWind, R"("events": [{"step": 5, "wind": )" + bidi(4, 5) + "}]"));
  EXPECT_TRUE(has(we,
                  "events[0].wind.bidirectional.period_steps = 4 is shorter than 1 + "
                  "events[0].wind.bidirectional.flux_ratio = 6 steps"))
      << we;
  EXPECT_TRUE(wind_period_warnings(job(1.0, kModelWind)).empty());
}

// Each warning's finest cell resolves its length (and coarser cells do not).
TEST(Resolution, TheFinestCellGivenResolvesTheLength) {
  const erg::v1::JobSpec coarse[] = {
      job(1.0, kShearWind), job(4.0, kModelWind), job(10.0, kModelWind),
      job(1.0, kModelWind, R"("model": {"max_hop_m": 1.5})"),
      job(2.0, kModelWind, R"("model": {"echo_reach_m": 6, "echo_dunes": true})")};
  for (const auto& spec : coarse) {
    const auto before = unresolved_lengths(spec);
    ASSERT_FALSE(before.empty());
    for (const auto& u : before) {
      ASSERT_GT(u.finest_m, 0) << u.warning;
      erg::v1::JobSpec finer = spec;
      finer.mutable_domain()->set_cell_size_m(u.finest_m);
      for (const auto& v : unresolved_lengths(finer)) EXPECT_NE(v.field, u.field) << v.warning;
      finer.mutable_domain()->set_cell_size_m(u.finest_m * 1.01);
      bool still = false;
      for (const auto& v : unresolved_lengths(finer)) still = still || v.field == u.field;
      EXPECT_TRUE(still) << u.field;
    }
  }
}

}  // namespace
}  // namespace erg
