// SPDX-License-Identifier: Apache-2.0
// Wind regimes (wind::regime_at, wind::at_step): direction convention, wind
// rose frequencies, holds and seeds, series interpolation along the shorter
// arc, clamping and periods, the bidirectional duty cycle, and regime switches
// by wind events with the regime's own clock.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "job/spec.h"
#include "wind/regime.h"

namespace erg::wind {
namespace {

using erg::v1::JobSpec;
using erg::v1::WindRegime;

// A regime from its JSON, with defaults (as the job would give it).
WindRegime regime_of(const std::string& json) {
  JobSpec s = erg::job::parse_json(R"({"wind": )" + json + "}");
  erg::job::apply_defaults(s);
  return s.wind();
}

double speed_of(Vec2 v) {
  return std::hypot(static_cast<double>(v.x), static_cast<double>(v.y));
}

// Direction in degrees in [0, 360).
double angle_of(Vec2 v) {
  double a = std::atan2(static_cast<double>(v.y), static_cast<double>(v.x)) * 180.0 /
             3.14159265358979323846;
  if (a < 0) a += 360.0;
  if (a >= 360.0) a -= 360.0;
  return a;
}

// Signed difference a - b of two directions, in (-180, 180].
double angle_diff(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d > 180) d -= 360;
  if (d <= -180) d += 360;
  return d;
}

#define EXPECT_WIND(v, speed, deg)                            \
  do {                                                        \
    const Vec2 w_ = (v);                                      \
    EXPECT_NEAR(speed_of(w_), (speed), 1e-4 * (1 + (speed))); \
    if ((speed) > 0) {                                        \
      EXPECT_NEAR(angle_diff(angle_of(w_), (deg)), 0, 1e-3);  \
    }                                                         \
  } while (0)

// ---- constant ------------------------------------------------------------------------

TEST(ConstantWind, DirectionIsCounterClockwiseFromEast) {
  auto at = [](double deg) {
    return regime_at(regime_of(R"({"constant": {"speed_mps": 10, "direction_deg": )" +
                               std::to_string(deg) + "}}"),
                     0, 0, 1);
  };
  Vec2 v = at(90);  // towards +y (north)
  EXPECT_NEAR(v.x, 0, 1e-5);
  EXPECT_NEAR(v.y, 10, 1e-5);
  v = at(0);  // towards +x (east)
  EXPECT_NEAR(v.x, 10, 1e-5);
  EXPECT_NEAR(v.y, 0, 1e-5);
  v = at(180);
  EXPECT_NEAR(v.x, -10, 1e-5);
  EXPECT_NEAR(v.y, 0, 1e-5);
  v = at(-90);
  EXPECT_NEAR(v.x, 0, 1e-5);
  EXPECT_NEAR(v.y, -10, 1e-5);
  v = at(45);
  EXPECT_NEAR(v.x, 10 / std::sqrt(2.0), 1e-5);
  EXPECT_NEAR(v.y, 10 / std::sqrt(2.0), 1e-5);
  v = direction(90);
  EXPECT_NEAR(v.x, 0, 1e-7);
  EXPECT_NEAR(v.y, 1, 1e-7);
  v = direction(270);
  EXPECT_NEAR(v.y, -1, 1e-7);
}

TEST(ConstantWind, DefaultDirectionIsEastAndStepsDoNotMatter) {
  const WindRegime r = regime_of(R"({"constant": {"speed_mps": 3}})");
  for (std::int64_t s : {0, 1, 17, 1000000}) {
    const Vec2 v = regime_at(r, s, s + 5, 99);
    EXPECT_FLOAT_EQ(v.x, 3);
    EXPECT_FLOAT_EQ(v.y, 0);
  }
}

// ---- wind rose ------------------------------------------------------------------------

const char* kRose = R"({"rose": {"entries": [
    {"direction_deg": 0, "speed_mps": 5, "probability": 0.5},
    {"direction_deg": 90, "speed_mps": 8, "probability": 0.3},
    {"direction_deg": 200, "speed_mps": 12, "probability": 0.2}]}})";

// Which entry of kRose a wind is (by its speed and direction); -1 if none.
int rose_entry(Vec2 v) {
  const double s = speed_of(v), a = angle_of(v);
  if (std::fabs(s - 5) < 1e-4 && std::fabs(angle_diff(a, 0)) < 1e-3) return 0;
  if (std::fabs(s - 8) < 1e-4 && std::fabs(angle_diff(a, 90)) < 1e-3) return 1;
  if (std::fabs(s - 12) < 1e-4 && std::fabs(angle_diff(a, 200)) < 1e-3) return 2;
  return -1;
}

TEST(WindRose, FrequenciesMatchTheProbabilities) {
  const WindRegime r = regime_of(kRose);
  const double p[3] = {0.5, 0.3, 0.2};
  for (std::uint64_t seed : {1ull, 12345ull}) {
    const int n = 20000;
    int count[3] = {0, 0, 0};
    for (int s = 0; s < n; ++s) {
      const int e = rose_entry(regime_at(r, s, s, seed));
      ASSERT_GE(e, 0) << "step " << s << " is no entry of the rose";
      ++count[e];
    }
    double chi2 = 0;
    for (int k = 0; k < 3; ++k) chi2 += std::pow(count[k] - n * p[k], 2) / (n * p[k]);
    // 2 degrees of freedom: P(chi2 > 13.8) = 0.001.
    EXPECT_LT(chi2, 13.8) << "seed " << seed << ": " << count[0] << " " << count[1] << " "
                          << count[2];
  }
}

TEST(WindRose, ZeroProbabilityEntryIsNeverDrawn) {
  const WindRegime r = regime_of(R"({"rose": {"entries": [
      {"direction_deg": 0, "speed_mps": 5, "probability": 0},
      {"direction_deg": 90, "speed_mps": 8, "probability": 1},
      {"direction_deg": 180, "speed_mps": 9, "probability": 0}]}})");
  for (int s = 0; s < 2000; ++s) EXPECT_WIND(regime_at(r, s, s, 3), 8, 90);
}

TEST(WindRose, HoldStepsHoldADraw) {
  const WindRegime r = regime_of(R"({"rose": {"hold_steps": 7, "entries": [
      {"direction_deg": 0, "speed_mps": 5, "probability": 0.5},
      {"direction_deg": 90, "speed_mps": 8, "probability": 0.3},
      {"direction_deg": 200, "speed_mps": 12, "probability": 0.2}]}})");
  int changes = 0;
  std::map<int, int> count;
  const int holds = 3000;
  for (int h = 0; h < holds; ++h) {
    const Vec2 first = regime_at(r, 7 * h, 7 * h, 5);
    ++count[rose_entry(first)];
    for (int k = 1; k < 7; ++k) {
      const Vec2 v = regime_at(r, 7 * h + k, 7 * h + k, 5);
      ASSERT_EQ(v.x, first.x) << "hold " << h << " step " << k;
      ASSERT_EQ(v.y, first.y) << "hold " << h << " step " << k;
    }
    if (h > 0) {
      const Vec2 prev = regime_at(r, 7 * h - 1, 7 * h - 1, 5);
      changes += prev.x != first.x || prev.y != first.y;
    }
  }
  // A new draw repeats the previous entry with P = 0.25 + 0.09 + 0.04 = 0.38.
  EXPECT_NEAR(changes / double(holds - 1), 0.62, 0.04);
  EXPECT_EQ(count.count(-1), 0u);
  EXPECT_NEAR(count[0] / double(holds), 0.5, 0.04);
  EXPECT_NEAR(count[1] / double(holds), 0.3, 0.04);
  EXPECT_NEAR(count[2] / double(holds), 0.2, 0.04);
}

TEST(WindRose, SameSeedSameSequenceOtherSeedOtherSequence) {
  const WindRegime r = regime_of(kRose);
  int differ = 0, differ_global = 0;
  for (int s = 0; s < 500; ++s) {
    const Vec2 a = regime_at(r, s, s, 42), b = regime_at(r, s, s, 42), c = regime_at(r, s, s, 43);
    EXPECT_EQ(a.x, b.x);
    EXPECT_EQ(a.y, b.y);
    differ += a.x != c.x || a.y != c.y;
    // The draw depends on the global step, not on the regime's own clock.
    const Vec2 d = regime_at(r, s + 11, s, 42);
    EXPECT_EQ(a.x, d.x);
    EXPECT_EQ(a.y, d.y);
    const Vec2 e = regime_at(r, s, s + 1, 42);
    differ_global += a.x != e.x || a.y != e.y;
  }
  // Two independent draws differ with P = 0.62.
  EXPECT_GT(differ, 500 * 0.5);
  EXPECT_GT(differ_global, 500 * 0.5);
}

TEST(WindRose, SectorWidthSpreadsDirections) {
  const WindRegime r = regime_of(R"({"rose": {"sector_width_deg": 40, "entries": [
      {"direction_deg": 10, "speed_mps": 6, "probability": 1}]}})");
  double lo = 1e9, hi = -1e9, sum = 0;
  const int n = 4000;
  for (int s = 0; s < n; ++s) {
    const Vec2 v = regime_at(r, s, s, 8);
    EXPECT_NEAR(speed_of(v), 6, 1e-4);
    const double d = angle_diff(angle_of(v), 10);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
    sum += d;
  }
  EXPECT_GE(lo, -20 - 1e-3);
  EXPECT_LE(hi, 20 + 1e-3);
  EXPECT_LT(lo, -19);
  EXPECT_GT(hi, 19);
  EXPECT_NEAR(sum / n, 0, 1.0);  // uniform over +-20: standard error 0.18
}

// ---- series ----------------------------------------------------------------------------

TEST(WindSeries, InterpolatesLinearlyAlongTheShorterArcAndClamps) {
  const WindRegime r = regime_of(R"({"series": {"keyframes": [
      {"step": 10, "speed_mps": 2, "direction_deg": 350},
      {"step": 20, "speed_mps": 12, "direction_deg": 10}]}})");
  for (int t = 0; t <= 10; ++t) EXPECT_WIND(regime_at(r, t, t, 1), 2, 350);  // before: first
  EXPECT_WIND(regime_at(r, 12, 12, 1), 4, 354);
  EXPECT_WIND(regime_at(r, 15, 15, 1), 7, 0);  // through 0, not through 180
  EXPECT_WIND(regime_at(r, 18, 18, 1), 10, 6);
  for (int t = 11; t < 20; ++t) {
    const Vec2 v = regime_at(r, t, t, 1);
    EXPECT_NEAR(speed_of(v), 2 + (t - 10), 1e-4) << t;
    EXPECT_NEAR(angle_diff(angle_of(v), 350 + 2.0 * (t - 10)), 0, 1e-3) << t;
    EXPECT_GT(v.x, 0) << t;  // never swings round through the west
  }
  for (int t : {20, 21, 100, 1000000}) EXPECT_WIND(regime_at(r, t, t, 1), 12, 10);  // after: last
}

TEST(WindSeries, ShorterArcTheOtherWayAndAcross180) {
  const WindRegime down = regime_of(R"({"series": {"keyframes": [
      {"step": 0, "speed_mps": 5, "direction_deg": 10},
      {"step": 10, "speed_mps": 5, "direction_deg": 350}]}})");
  EXPECT_WIND(regime_at(down, 2, 2, 1), 5, 6);
  EXPECT_WIND(regime_at(down, 5, 5, 1), 5, 0);
  EXPECT_WIND(regime_at(down, 8, 8, 1), 5, 354);
  const WindRegime west = regime_of(R"({"series": {"keyframes": [
      {"step": 0, "speed_mps": 5, "direction_deg": 170},
      {"step": 4, "speed_mps": 5, "direction_deg": -170}]}})");
  EXPECT_WIND(regime_at(west, 1, 1, 1), 5, 175);
  EXPECT_WIND(regime_at(west, 2, 2, 1), 5, 180);
  EXPECT_WIND(regime_at(west, 3, 3, 1), 5, 185);
  const WindRegime wide = regime_of(R"({"series": {"keyframes": [
      {"step": 0, "speed_mps": 5, "direction_deg": -300},
      {"step": 10, "speed_mps": 5, "direction_deg": 300}]}})");  // 60 and -60: 120 apart via 0
  EXPECT_WIND(regime_at(wide, 5, 5, 1), 5, 0);
}

TEST(WindSeries, SpeedIsPiecewiseLinear) {
  const WindRegime r = regime_of(R"({"series": {"keyframes": [
      {"step": 0, "speed_mps": 0}, {"step": 10, "speed_mps": 10}, {"step": 30, "speed_mps": 0}]}})");
  const double want[] = {0, 1, 5, 10, 7.5, 5, 2.5, 0, 0};
  const int steps[] = {0, 1, 5, 10, 15, 20, 25, 30, 31};
  for (int k = 0; k < 9; ++k)
    EXPECT_NEAR(speed_of(regime_at(r, steps[k], steps[k], 1)), want[k], 1e-4) << steps[k];
}

TEST(WindSeries, RepeatsWithPeriodSteps) {
  const WindRegime r = regime_of(R"({"series": {"period_steps": 20, "keyframes": [
      {"step": 0, "speed_mps": 0}, {"step": 10, "speed_mps": 10}]}})");
  // A triangle wave: up over the keyframes, back down over the period's end.
  auto tri = [](int t) {
    const int p = t % 20;
    return p <= 10 ? p : 20 - p;
  };
  for (int t = 0; t <= 200; ++t) EXPECT_NEAR(speed_of(regime_at(r, t, t, 1)), tri(t), 1e-4) << t;
  EXPECT_NEAR(speed_of(regime_at(r, 1000005, 0, 1)), 5, 1e-4);
}

TEST(WindSeries, PeriodicSeriesWhoseFirstKeyframeIsLateWrapsContinuously) {
  // Keyframes at 5 and 15 in a period of 20: from 15 the wind goes back to
  // the first keyframe's value, reached at step 5 of the next period.
  const WindRegime r = regime_of(R"({"series": {"period_steps": 20, "keyframes": [
      {"step": 5, "speed_mps": 0, "direction_deg": 0},
      {"step": 15, "speed_mps": 10, "direction_deg": 90}]}})");
  auto tri = [](int t) {
    const int p = ((t - 5) % 20 + 20) % 20;
    return p <= 10 ? p : 20 - p;
  };
  for (int t = 0; t <= 100; ++t)
    EXPECT_NEAR(speed_of(regime_at(r, t, t, 1)), tri(t), 1e-4) << "step " << t;
  EXPECT_WIND(regime_at(r, 10, 10, 1), 5, 45);
  EXPECT_WIND(regime_at(r, 20, 20, 1), 5, 45);  // halfway back from 90 to 0
  EXPECT_WIND(regime_at(r, 2, 2, 1), 3, 27);
}

TEST(WindSeries, SingleKeyframeIsConstant) {
  const WindRegime r = regime_of(R"({"series": {"keyframes": [
      {"step": 3, "speed_mps": 4, "direction_deg": 45}]}})");
  for (int t : {0, 3, 4, 99}) EXPECT_WIND(regime_at(r, t, t, 1), 4, 45);
  const WindRegime p = regime_of(R"({"series": {"period_steps": 10, "keyframes": [
      {"step": 3, "speed_mps": 4, "direction_deg": 45}]}})");
  for (int t : {0, 3, 4, 9, 10, 99}) EXPECT_WIND(regime_at(p, t, t, 1), 4, 45);
}

// ---- bidirectional --------------------------------------------------------------------

struct Duty {
  int primary = 0, secondary = 0;
};

Duty duty(const WindRegime& r, double speed, double primary_deg, double secondary_deg, int period,
          int periods) {
  Duty d;
  for (int t = 0; t < period * periods; ++t) {
    const Vec2 v = regime_at(r, t, 1000 + t, 1);
    EXPECT_NEAR(speed_of(v), speed, 1e-4) << t;
    const double a = angle_of(v);
    if (std::fabs(angle_diff(a, primary_deg)) < 1e-3)
      ++d.primary;
    else if (std::fabs(angle_diff(a, secondary_deg)) < 1e-3)
      ++d.secondary;
    else
      ADD_FAILURE() << "step " << t << ": direction " << a << " is neither wind";
  }
  return d;
}

TEST(Bidirectional, EqualFluxesAlternateHalfAndHalf) {
  const WindRegime r =
      regime_of(R"({"bidirectional": {"speed_mps": 6, "direction_deg": 30, "angle_deg": 120}})");
  const Duty d = duty(r, 6, 30, 150, 20, 10);
  EXPECT_EQ(d.primary, 100);
  EXPECT_EQ(d.secondary, 100);
  // The primary blows first in each period, then the secondary.
  for (int p = 0; p < 3; ++p) {
    for (int t = 0; t < 10; ++t) EXPECT_WIND(regime_at(r, 20 * p + t, 0, 1), 6, 30);
    for (int t = 10; t < 20; ++t) EXPECT_WIND(regime_at(r, 20 * p + t, 0, 1), 6, 150);
  }
}

// The regime of `json` over `periods` periods blows each wind for so many steps.
void expect_duty(const std::string& json, double speed, double primary_deg, double secondary_deg,
                 int period, int periods, int primary, int secondary) {
  const Duty d = duty(regime_of(json), speed, primary_deg, secondary_deg, period, periods);
  EXPECT_EQ(d.primary, primary) << json;
  EXPECT_EQ(d.secondary, secondary) << json;
}

TEST(Bidirectional, FluxRatioThreeGivesThreeQuarters) {
  expect_duty(R"({"bidirectional": {"speed_mps": 9, "direction_deg": -45, "angle_deg": 100,
                                    "flux_ratio": 3}})",
              9, 315, 55, 20, 10, 150, 50);
  expect_duty(R"({"bidirectional": {"speed_mps": 9, "angle_deg": 180, "flux_ratio": 3,
                                    "period_steps": 8}})",
              9, 0, 180, 8, 25, 150, 50);
}

TEST(Bidirectional, ExtremeRatioStillBlowsBothWinds) {
  // 1000 : 1 over periods of 10 steps: the secondary blows 10 steps in 1001
  // periods (one step in about one period of 100), so both winds blow and
  // the ratio is kept exactly.
  expect_duty(R"({"bidirectional": {"speed_mps": 4, "angle_deg": 90, "flux_ratio": 1000,
                                    "period_steps": 10}})",
              4, 0, 90, 10, 1001, 10000, 10);
}

TEST(Bidirectional, RatioThatDoesNotDivideThePeriodIsKeptOverThePeriods) {
  // N = 2 over 20 steps: 40/3 primary steps a period. The primary takes 13,
  // 13 and 14 steps in turn, first in each period; rounding every period to
  // 13 would blow a ratio of 13 : 7 = 1.86.
  const std::string json = R"({"bidirectional": {"speed_mps": 5, "angle_deg": 120,
                                                 "flux_ratio": 2, "period_steps": 20}})";
  expect_duty(json, 5, 0, 120, 20, 30, 400, 200);
  const WindRegime r = regime_of(json);
  const int expected_primary[3] = {13, 13, 14};
  for (int p = 0; p < 6; ++p)
    for (int t = 0; t < 20; ++t)
      EXPECT_WIND(regime_at(r, 20 * p + t, 0, 1), 5, t < expected_primary[p % 3] ? 0 : 120);
  // A period too short to split: 2 steps under N = 2 give the primary 1, 1
  // and 2 steps in turn, 4 of every 6.
  expect_duty(R"({"bidirectional": {"speed_mps": 5, "angle_deg": 120, "flux_ratio": 2,
                                    "period_steps": 2}})",
              5, 0, 120, 2, 3, 4, 2);
}

// ---- at_step: switching regimes -------------------------------------------------------

JobSpec job_of(const std::string& json) {
  JobSpec s = erg::job::parse_json(json);
  erg::job::apply_defaults(s);
  return s;
}

TEST(AtStep, WindEventsSwitchTheRegimeAndRestartItsClock) {
  const JobSpec spec = job_of(R"({
    "domain": {"nx": 16, "ny": 16, "cell_size_m": 1},
    "wind": {"constant": {"speed_mps": 5, "direction_deg": 0}},
    "events": [
      {"step": 50, "sand": {"x_m": 1, "y_m": 1, "radius_m": 1, "height": 1}},
      {"step": 150, "wind": {"bidirectional": {"speed_mps": 6, "direction_deg": 0, "angle_deg": 90,
                                               "period_steps": 10}}},
      {"step": 100, "wind": {"series": {"keyframes": [{"step": 0, "speed_mps": 0, "direction_deg": 90},
                                                      {"step": 10, "speed_mps": 10, "direction_deg": 90}]}}}
    ]})");
  for (int s : {0, 1, 49, 50, 51, 99}) {
    SCOPED_TRACE(s);
    EXPECT_WIND(at_step(spec, s), 5, 0);
  }
  // The series counts from its event: step 100 is its step 0.
  EXPECT_NEAR(speed_of(at_step(spec, 100)), 0, 1e-6);
  EXPECT_WIND(at_step(spec, 103), 3, 90);
  EXPECT_WIND(at_step(spec, 105), 5, 90);
  for (int s : {110, 120, 149}) {
    SCOPED_TRACE(s);
    EXPECT_WIND(at_step(spec, s), 10, 90);
  }
  // The bidirectional period starts at 150 (listed before the series event).
  for (int s = 150; s < 160; ++s) {
    SCOPED_TRACE(s);
    EXPECT_WIND(at_step(spec, s), 6, s < 155 ? 0 : 90);
  }
  EXPECT_WIND(at_step(spec, 160), 6, 0);
  EXPECT_WIND(at_step(spec, 100155), 6, 90);
}

TEST(AtStep, EventAtStepZeroAndEventsAtTheSameStep) {
  const JobSpec spec = job_of(R"({
    "domain": {"nx": 16, "ny": 16, "cell_size_m": 1},
    "wind": {"constant": {"speed_mps": 5}},
    "events": [
      {"step": 0, "wind": {"constant": {"speed_mps": 7, "direction_deg": 180}}},
      {"step": 20, "wind": {"constant": {"speed_mps": 1, "direction_deg": 0}}},
      {"step": 20, "wind": {"constant": {"speed_mps": 2, "direction_deg": 270}}}
    ]})");
  EXPECT_WIND(at_step(spec, 0), 7, 180);
  EXPECT_WIND(at_step(spec, 19), 7, 180);
  // Events at the same step apply in file order: the last one wins.
  EXPECT_WIND(at_step(spec, 20), 2, 270);
  EXPECT_WIND(at_step(spec, 500), 2, 270);
}

TEST(AtStep, RoseDrawsFollowTheSeedAndTheGlobalStep) {
  JobSpec spec = job_of(std::string(R"({"domain": {"nx": 16, "ny": 16, "cell_size_m": 1},
    "seed": 7, "wind": )") +
                        kRose + R"(, "events": [{"step": 100, "wind": {"rose": {"entries": [
      {"direction_deg": 45, "speed_mps": 3, "probability": 0.5},
      {"direction_deg": 135, "speed_mps": 4, "probability": 0.5}], "hold_steps": 4}}}]})");
  for (int s = 0; s < 100; ++s) {
    const Vec2 a = at_step(spec, s), b = regime_at(spec.wind(), s, s, 7);
    EXPECT_EQ(a.x, b.x) << s;
    EXPECT_EQ(a.y, b.y) << s;
  }
  for (int s = 100; s < 300; ++s) {
    const Vec2 a = at_step(spec, s), b = regime_at(spec.events(0).wind(), s - 100, s, 7);
    EXPECT_EQ(a.x, b.x) << s;
    EXPECT_EQ(a.y, b.y) << s;
  }
  JobSpec other = spec;
  other.set_seed(8);
  int differ = 0;
  for (int s = 0; s < 100; ++s) {
    const Vec2 a = at_step(spec, s), b = at_step(other, s);
    differ += a.x != b.x || a.y != b.y;
  }
  EXPECT_GT(differ, 40);
}

}  // namespace
}  // namespace erg::wind
