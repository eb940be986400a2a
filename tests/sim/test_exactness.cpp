// SPDX-License-Identifier: Apache-2.0
// Exactness (docs/design.md, "Exactness"): over 1000 steps on a
// non-square torus with the wind at 30 degrees to the grid, sand is conserved
// to the unit (sand + bedrock with abrasion), never negative, and the fields
// are bitwise identical for 1, 2 and 4 threads and between two runs, in both
// transport modes.
#include <gtest/gtest.h>

#include <string>

#include "sim_test_util.h"

namespace erg::test {
namespace {

std::string exact_job(const std::string& transport, bool abrasion) {
  // Non-square, with bedrock relief, thin and thick sand, vegetation and
  // resistance variations, a vortex over the corner of the torus and an
  // evolving turbulence [P19 4.4], so that every stage and coupling is active.
  return std::string(R"({
    "domain": {"nx": 72, "ny": 40, "cell_size_m": 1.0},
    "layers": {
      "bedrock": {"fbm": {"amplitude": 3, "wavelength_m": 40, "octaves": 3}},
      "sand": {"patches": {"coverage": 0.4, "radius_m": 6, "height": 2.5, "falloff_m": 3},
               "piles": [{"x_m": 20, "y_m": 20, "height": 6, "radius_m": 8}]},
      "vegetation": {"fbm": {"amplitude": 0.6, "offset": 0.1, "wavelength_m": 30, "octaves": 2}},
      "resistance": {"fbm": {"amplitude": 0.5, "offset": 0.5, "wavelength_m": 20, "octaves": 2}}
    },
    "wind": {"constant": {"speed_mps": 6.5, "direction_deg": 30}},
    "wind_primitives": [{"vortex": {"x_m": 70, "y_m": 38, "radius_m": 6, "peak_speed_mps": 3}},
                        {"turbulence": {"amplitude_mps": 1, "wavelength_m": 12,
                                        "period_steps": 50, "drift_m_per_step": 0.2}}],
    "model": {"abrasion_k": )") +
         (abrasion ? "0.05" : "0") + R"(, "avalanche_iterations": 20,
              "bedrock_avalanche_iterations": 1, "bedrock_to_sand": )" +
         (abrasion ? "true" : "false") + R"(},
    "transport": ")" +
         transport + R"(",
    "seed": 11,
    "run": {"steps": 1000}
  })";
}

struct Outcome {
  TileState state;
  Totals totals;
};

// Runs the job, checking conservation and sand >= 0 along the way.
Outcome run_checked(const std::string& json, int threads, bool abrasion, int steps) {
  Simulation sim(spec_from(json), ".", cpu_threads(threads));
  const Totals t0 = sim.totals();
  EXPECT_GT(t0.sand, 0);
  for (int s = 1; s <= steps; ++s) {
    sim.step();
    if (s % 100 == 0 || s == steps) {
      const Totals t = sim.totals();
      if (abrasion) {
        EXPECT_EQ(to_decimal(t.all_sand() + t.bedrock), to_decimal(t0.all_sand() + t0.bedrock))
            << "sand + bedrock changed by step " << s;
      } else {
        EXPECT_EQ(to_decimal(t.all_sand()), to_decimal(t0.all_sand()))
            << "sand changed by step " << s;
        EXPECT_EQ(to_decimal(t.bedrock), to_decimal(t0.bedrock)) << "bedrock changed by step " << s;
      }
      const TileState st = sim.state();
      long negative = 0;
      for (int y = 0; y < st.geom.ny; ++y)
        for (int x = 0; x < st.geom.nx; ++x)
          negative += (st.units[erg::fields::kSand](x, y) < 0) +
                      (st.units[erg::fields::kAirborne](x, y) < 0);
      EXPECT_EQ(negative, 0) << "cells with negative sand or airborne sand at step " << s;
    }
  }
  return {sim.state(), sim.totals()};
}

void expect_bitwise_equal(const TileState& a, const TileState& b, const std::string& what) {
  EXPECT_TRUE(owned(a.units[erg::fields::kSand]) == owned(b.units[erg::fields::kSand]))
      << what << ": sand differs";
  EXPECT_TRUE(owned(a.units[erg::fields::kBedrock]) == owned(b.units[erg::fields::kBedrock]))
      << what << ": bedrock differs";
  EXPECT_TRUE(owned(a.units[erg::fields::kAirborne]) == owned(b.units[erg::fields::kAirborne]))
      << what << ": airborne sand differs";
}

class Exactness : public ::testing::TestWithParam<std::tuple<std::string, bool>> {};

TEST_P(Exactness, ConservedNonNegativeAndThreadInvariant) {
  const auto& [transport, abrasion] = GetParam();
  const std::string json = exact_job(transport, abrasion);
  const Outcome one = run_checked(json, 1, abrasion, 1000);
  const Outcome two = run_checked(json, 2, abrasion, 1000);
  const Outcome four = run_checked(json, 4, abrasion, 1000);
  const Outcome again = run_checked(json, 2, abrasion, 1000);
  expect_bitwise_equal(one.state, two.state, "1 vs 2 threads");
  expect_bitwise_equal(one.state, four.state, "1 vs 4 threads");
  expect_bitwise_equal(two.state, again.state, "two runs");
  // The run did something: sand moved, and with abrasion bedrock was abraded.
  Simulation fresh(spec_from(json), ".", cpu_threads(1));
  EXPECT_FALSE(owned(fresh.state().units[erg::fields::kSand]) ==
               owned(one.state.units[erg::fields::kSand]))
      << "nothing moved";
  if (abrasion) {
    EXPECT_LT(one.totals.bedrock, fresh.totals().bedrock) << "no abrasion happened";
  }
}

INSTANTIATE_TEST_SUITE_P(Modes, Exactness,
                         ::testing::Combine(::testing::Values("EXPECTED", "STOCHASTIC"),
                                            ::testing::Bool()),
                         [](const auto& info) {
                           return std::get<0>(info.param) +
                                  (std::get<1>(info.param) ? "_abrasion" : "_no_abrasion");
                         });

// Timeline events change the totals by exactly what the ledger records.
TEST(Exactness, EventsAreAccountedToTheUnit) {
  const std::string json = R"({
    "domain": {"nx": 48, "ny": 40, "cell_size_m": 2.0},
    "layers": {"sand": {"constant": 0.5}},
    "wind": {"constant": {"speed_mps": 5, "direction_deg": 30}},
    "events": [
      {"step": 3, "sand": {"x_m": 90, "y_m": 40, "radius_m": 20, "falloff_m": 8, "height": 3}},
      {"step": 5, "sand": {"x_m": 10, "y_m": 10, "radius_m": 30, "falloff_m": 10, "height": -2}},
      {"step": 7, "bedrock": {"x_m": 50, "y_m": 50, "radius_m": 25, "falloff_m": 10, "height": -4}}
    ],
    "run": {"steps": 20}})";
  Simulation sim(spec_from(json), ".", cpu_threads(2));
  const Totals t0 = sim.totals();
  for (int s = 0; s < 20; ++s) sim.step();
  const Totals t = sim.totals();
  EXPECT_GT(sim.sand_added_by_events(), 0);  // +3 m disk beats the clamped -2 m one
  EXPECT_LT(sim.bedrock_added_by_events(), 0);
  EXPECT_EQ(to_decimal(t.all_sand()), to_decimal(t0.all_sand() + sim.sand_added_by_events()));
  EXPECT_EQ(to_decimal(t.bedrock), to_decimal(t0.bedrock + sim.bedrock_added_by_events()));
}

// Obstacles (stages/obstacles.h): a rock, a building, a road and, by events,
// a wall built on sand and later removed; echo dunes on, in front of a
// steep bedrock mesa. Over 250 steps in both transport
// modes with abrasion on: sand + bedrock stays exact (what the events removed
// is in the ledger), no sand ever lies or flies inside an obstacle, and 1, 2
// and 4 threads give the same bits.
class ExactnessObstacles : public ::testing::TestWithParam<std::string> {};

TEST_P(ExactnessObstacles, ConservedNoSandInsideAndThreadInvariant) {
  const std::string json = R"({
    "domain": {"nx": 72, "ny": 40, "cell_size_m": 1.0},
    "layers": {
      "bedrock": {"fbm": {"amplitude": 3, "wavelength_m": 40, "octaves": 3},
                  "piles": [{"x_m": 50, "y_m": 10, "height": 6, "radius_m": 7, "shape": "CYLINDER"}]},
      "sand": {"patches": {"coverage": 0.5, "radius_m": 6, "height": 2.5, "falloff_m": 3},
               "constant": 0.3},
      "obstacles": {"shapes": [
        {"height_m": 3, "disk": {"x_m": 30, "y_m": 12, "radius_m": 4}},
        {"height_m": 6, "rect": {"x_m": 60, "y_m": 25, "size_x_m": 5, "size_y_m": 20}},
        {"height_m": 0.2, "road": {"points": [{"x_m": 0, "y_m": 30}, {"x_m": 40, "y_m": 36},
                                              {"x_m": 50, "y_m": 20}], "width_m": 2.5}}]}
    },
    "wind": {"constant": {"speed_mps": 6.5, "direction_deg": 30}},
    "events": [
      {"step": 50, "add_obstacle": {"height_m": 2, "rect": {"x_m": 10, "y_m": 2, "size_x_m": 2, "size_y_m": 12}}},
      {"step": 90, "sand": {"x_m": 30, "y_m": 12, "radius_m": 9, "height": 2}},
      {"step": 180, "remove_obstacle": {"rect": {"x_m": 10, "y_m": 2, "size_x_m": 2, "size_y_m": 12}}}
    ],
    "model": {"abrasion_k": 0.05, "avalanche_iterations": 20, "bedrock_to_sand": true,
              "echo_dunes": true, "echo_reach_m": 12},
    "transport": ")" + GetParam() +
                           R"(",
    "seed": 5
  })";
  auto run = [&](int threads) {
    Simulation sim(spec_from(json), ".", cpu_threads(threads));
    const Totals t0 = sim.totals();
    long inside = 0, obstacle_cells = 0;
    for (int s = 1; s <= 250; ++s) {
      sim.step();
      if (s % 50 == 0) {
        const Totals t = sim.totals();
        EXPECT_EQ(to_decimal(t.all_sand() + t.bedrock),
                  to_decimal(t0.all_sand() + t0.bedrock + sim.sand_added_by_events()))
            << "sand + bedrock changed by step " << s;
        const TileState st = sim.state();
        for (int y = 0; y < st.geom.ny; ++y)
          for (int x = 0; x < st.geom.nx; ++x) {
            EXPECT_GE(st.units[erg::fields::kSand](x, y), 0);
            if (!obstacles::is_obstacle(st.reals[erg::fields::kObstacles](x, y))) continue;
            ++obstacle_cells;
            inside += st.units[erg::fields::kSand](x, y) != 0 ||
                      st.units[erg::fields::kAirborne](x, y) != 0;
          }
      }
    }
    EXPECT_EQ(inside, 0) << "obstacle cells holding sand";
    EXPECT_GT(obstacle_cells, 5 * 200);  // the shapes are there (about 230 cells each check)
    return sim.state();
  };
  const TileState one = run(1), two = run(2), four = run(4);
  expect_bitwise_equal(one, two, "1 vs 2 threads");
  expect_bitwise_equal(one, four, "1 vs 4 threads");
}

INSTANTIATE_TEST_SUITE_P(Modes, ExactnessObstacles, ::testing::Values("EXPECTED", "STOCHASTIC"),
                         [](const auto& info) { return info.param; });

// A 10 m sand column at 0.5 m cells in a wind, with the defaults.
std::string settling_column_job() {
  return R"({
    "domain": {"nx": 80, "ny": 64, "cell_size_m": 0.5},
    "layers": {"sand": {"piles": [{"x_m": 20, "y_m": 16, "height": 10, "radius_m": 6,
                                   "shape": "CYLINDER"}]}},
    "wind": {"speed_is": "SHEAR_VELOCITY", "constant": {"speed_mps": 0.31, "direction_deg": 30}},
    "transport": "STOCHASTIC", "seed": 3, "model": {"slab_m": 0.05, "reptation_k": 0.2},
    "run": {"steps": 4}})";
}

// Avalanching iterates until settled (docs/design.md, "Avalanching until
// settled"): a 10 m column at 0.5 m cells needs hundreds of iterations in
// its first steps. The stop is exact (an iteration finds no donor or moves
// nothing: every later one would be the identity), so 1, 2 and 4 threads,
// and the rounds of one tile and of several (a first round of 4 then rounds
// of 46; of 4 then 7), give the same bits and the same iteration counts.
TEST(Exactness, SettlingIsThreadAndRoundInvariant) {
  const std::string column = settling_column_job();
  auto run = [&](int threads, AvalancheRounds rounds) {
    Placement place;
    place.rounds = rounds;
    Simulation sim(spec_from(column), ".", cpu_threads(threads), place);
    for (int s = 0; s < 4; ++s) sim.step();
    EXPECT_EQ(sim.times().avalanche_capped_steps, 0);
    return std::make_pair(sim.state(), sim.times());
  };
  const auto [one, times] = run(1, kOneTileRounds);
  EXPECT_GT(times.avalanche_most, kTiledRounds.length + kTiledRounds.later)
      << "settling too short to need several later rounds";
  const std::pair<int, AvalancheRounds> variants[] = {
      {2, kOneTileRounds}, {4, kOneTileRounds}, {2, kTiledRounds}, {1, AvalancheRounds{4, 7}}};
  for (const auto& [threads, rounds] : variants) {
    const std::string what = std::to_string(threads) + " threads, rounds of " +
                             std::to_string(rounds.length) + " then " +
                             std::to_string(rounds.later);
    const auto [state, t] = run(threads, rounds);
    expect_bitwise_equal(one, state, what);
    EXPECT_EQ(times.avalanche_iterations, t.avalanche_iterations) << what;
  }
}

}  // namespace
}  // namespace erg::test

namespace erg::test {
namespace {

// The CPU backend visits only the cells where an avalanching iteration can
// change something; visiting every cell must give the same bits.
TEST(Exactness, SparseAvalanchingEqualsVisitingEveryCell) {
  const std::string column = R"({
    "domain": {"nx": 96, "ny": 80, "cell_size_m": 1.0},
    "layers": {"bedrock": {"fbm": {"amplitude": 4, "wavelength_m": 32, "octaves": 3}},
               "sand": {"piles": [{"x_m": 40, "y_m": 40, "height": 60, "radius_m": 6, "shape": "CYLINDER"}],
                        "uniform": {"min": 0, "max": 1.5}},
               "vegetation": {"uniform": {"min": 0, "max": 0.6}}},
    "wind": {"constant": {"speed_mps": 6, "direction_deg": 30}},
    "model": {"avalanche_iterations": 40, "bedrock_avalanche_iterations": 3, "abrasion_k": 0.05,
              "bedrock_to_sand": true},
    "run": {"steps": 60}})";
  for (const std::string& json :
       {column, exact_job("EXPECTED", true), exact_job("STOCHASTIC", false)}) {
    RunOptions sparse = cpu_threads(2), everywhere = cpu_threads(2);
    everywhere.avalanche_everywhere = true;
    Simulation a(spec_from(json), ".", sparse), b(spec_from(json), ".", everywhere);
    for (int s = 0; s < 60; ++s) {
      a.step();
      b.step();
    }
    expect_bitwise_equal(a.state(), b.state(), "sparse vs everywhere");
    EXPECT_GT(a.times().avalanche_iterations, 0) << "nothing avalanched: the test proves nothing";
  }
}

// The same while a steep column settles over hundreds of iterations a step,
// where the cell masks matter most (a few slip-face cells move in each of
// the later iterations): one tile (its ghosts refilled before every
// iteration) and several tiles' rounds (a first round of 4, then rounds of
// 46 whose ghosts are refilled at each round start) both give the bits and
// the iteration counts of visiting every cell, with the defaults.
TEST(Exactness, SparseSettlingEqualsVisitingEveryCell) {
  const std::string column = settling_column_job();
  for (const AvalancheRounds rounds : {kOneTileRounds, kTiledRounds}) {
    auto run = [&](bool everywhere) {
      Placement place;
      place.rounds = rounds;
      RunOptions opt = cpu_threads(2);
      opt.avalanche_everywhere = everywhere;
      Simulation sim(spec_from(column), ".", opt, place);
      for (int s = 0; s < 3; ++s) sim.step();
      return std::make_pair(sim.state(), sim.times());
    };
    const std::string what =
        "rounds of " + std::to_string(rounds.length) + " then " + std::to_string(rounds.later);
    const auto [sparse, ts] = run(false);
    const auto [everywhere, te] = run(true);
    expect_bitwise_equal(sparse, everywhere, "sparse vs everywhere, " + what);
    EXPECT_EQ(ts.avalanche_iterations, te.avalanche_iterations) << what;
    EXPECT_EQ(ts.avalanche_capped_steps, 0) << what;
    EXPECT_GT(ts.avalanche_most, kTiledRounds.length + 2 * kTiledRounds.later)
        << what << ": settling too short to need several later rounds";
  }
}

// Ghost-zone rounds (backend/cpu/avalanching.cpp) are execution only: a
// refill before every iteration (one tile), rounds of 3, a first round of 4
// then rounds of 46 (several tiles; here the rest, 21), a first round of 4
// then wider rounds of 7, a first round of 3 then the rest, and all
// iterations in one round give the same fields, bit for bit. A 60 m sand
// column needs many more iterations than one round to spread, so every
// grouping refills, and the later rounds widen.
TEST(Exactness, AvalanchingRoundsDoNotChangeResults) {
  const std::string column = R"({
    "domain": {"nx": 96, "ny": 80, "cell_size_m": 1.0},
    "layers": {"bedrock": {"fbm": {"amplitude": 4, "wavelength_m": 32, "octaves": 3}},
               "sand": {"piles": [{"x_m": 40, "y_m": 40, "height": 60, "radius_m": 6, "shape": "CYLINDER"}],
                        "uniform": {"min": 0, "max": 1.5}},
               "vegetation": {"uniform": {"min": 0, "max": 0.6}}},
    "wind": {"constant": {"speed_mps": 6, "direction_deg": 30}},
    "model": {"avalanche_iterations": 25, "bedrock_avalanche_iterations": 6, "abrasion_k": 0.05,
              "bedrock_to_sand": true},
    "run": {"steps": 20}})";
  auto run = [&](AvalancheRounds rounds) {
    Placement place;
    place.rounds = rounds;
    Simulation sim(spec_from(column), ".", cpu_threads(2), place);
    for (int s = 0; s < 20; ++s) sim.step();
    return std::make_pair(sim.state(), sim.times().avalanche_iterations);
  };
  const auto [per_iteration, moved] = run(kOneTileRounds);
  EXPECT_GT(moved, 20 * kTiledRounds.length) << "avalanching too short to need several rounds";
  for (const AvalancheRounds rounds : {AvalancheRounds{3, 3}, kTiledRounds, AvalancheRounds{4, 7},
                                       AvalancheRounds{3, 0}, AvalancheRounds{0, 0}}) {
    const std::string what = "rounds of " + std::to_string(rounds.length) + " then " +
                             (rounds.later > 0 ? std::to_string(rounds.later) : "the rest");
    const auto [state, moved_too] = run(rounds);
    expect_bitwise_equal(per_iteration, state, what);
    EXPECT_EQ(moved, moved_too) << what;
  }
}

}  // namespace
}  // namespace erg::test
