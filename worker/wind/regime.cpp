// SPDX-License-Identifier: Apache-2.0
#include "wind/regime.h"

#include <cmath>

#include "core/philox.h"
#include "wind/physics.h"

namespace erg::wind {

namespace {
constexpr double kPi = 3.14159265358979323846;

Vec2 polar(double speed, double deg) {
  const double r = deg * kPi / 180.0;
  return {static_cast<float>(speed * std::cos(r)), static_cast<float>(speed * std::sin(r))};
}

// Angle b moved to within 180 degrees of a, for interpolation along the
// shorter arc.
double unwrap_near(double a, double b) {
  double d = std::fmod(b - a, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d < -180.0) d += 360.0;
  return a + d;
}
}  // namespace

Vec2 direction(double deg) {
  return polar(1.0, deg);
}

Vec2 regime_at(const erg::v1::WindRegime& regime, std::int64_t local_step, std::int64_t global_step,
               std::uint64_t seed) {
  using R = erg::v1::WindRegime;
  switch (regime.regime_case()) {
    case R::kConstant:
      return polar(regime.constant().speed_mps(), regime.constant().direction_deg());
    case R::kRose: {
      const auto& rose = regime.rose();
      // One draw per hold period, keyed by the global period index.
      const std::int64_t period = global_step / rose.hold_steps();
      const Philox4 r =
          random4(seed, static_cast<std::uint64_t>(period), 0, RandomStream::kWindRose);
      const double u = u01d(r.v[0], r.v[1]);
      double acc = 0;
      int pick = rose.entries_size() - 1;
      for (int k = 0; k < rose.entries_size(); ++k) {
        acc += rose.entries(k).probability();
        if (u < acc) {
          pick = k;
          break;
        }
      }
      const auto& e = rose.entries(pick);
      const double jitter = (u01d(r.v[2], r.v[3]) - 0.5) * rose.sector_width_deg();
      return polar(e.speed_mps(), e.direction_deg() + jitter);
    }
    case R::kSeries: {
      const auto& s = regime.series();
      std::int64_t t = local_step;
      const auto& first = s.keyframes(0);
      if (s.period_steps() > 0) {
        t %= s.period_steps();
        // Before the first keyframe of a period: still on the way back from
        // the previous period's last keyframe (the wrap segment below).
        if (t < first.step()) t += s.period_steps();
      }
      if (t <= first.step()) return polar(first.speed_mps(), first.direction_deg());
      for (int k = 1; k < s.keyframes_size(); ++k) {
        const auto& a = s.keyframes(k - 1);
        const auto& b = s.keyframes(k);
        if (t <= b.step()) {
          const double f =
              static_cast<double>(t - a.step()) / static_cast<double>(b.step() - a.step());
          const double speed = a.speed_mps() + f * (b.speed_mps() - a.speed_mps());
          const double bd = unwrap_near(a.direction_deg(), b.direction_deg());
          return polar(speed, a.direction_deg() + f * (bd - a.direction_deg()));
        }
      }
      if (s.period_steps() > 0) {
        // Wrap from the last keyframe back to the first over the period's end.
        const auto& a = s.keyframes(s.keyframes_size() - 1);
        const double span = static_cast<double>(s.period_steps() - a.step() + first.step());
        const double f = static_cast<double>(t - a.step()) / span;
        const double speed = a.speed_mps() + f * (first.speed_mps() - a.speed_mps());
        const double bd = unwrap_near(a.direction_deg(), first.direction_deg());
        return polar(speed, a.direction_deg() + f * (bd - a.direction_deg()));
      }
      const auto& last = s.keyframes(s.keyframes_size() - 1);
      return polar(last.speed_mps(), last.direction_deg());
    }
    case R::kBidirectional: {
      const auto& b = regime.bidirectional();
      const std::int64_t p = b.period_steps();
      const std::int64_t k = local_step / p;
      // The primary blows first in each period. Its steps over the first k
      // periods are floor(k p N / (1 + N)), so the two winds' durations, and
      // with equal speeds their sand fluxes, stand exactly in the ratio N
      // over the long run, as flux_ratio promises ([N24] 5), whatever the
      // period: a period of 20 steps under N = 2 gives the primary 13, 13
      // and 14 steps in turn, not 13 in every period (a ratio of 1.86).
      // The numerator first: k p N is exact for an integer N, so a quotient
      // that is a whole number comes out whole.
      const double n = b.flux_ratio();
      const auto primary_before = [p, n](std::int64_t periods) {
        return static_cast<std::int64_t>(
            std::floor(static_cast<double>(periods) * static_cast<double>(p) * n / (1.0 + n)));
      };
      const std::int64_t primary = primary_before(k + 1) - primary_before(k);
      const bool first = (local_step % p) < primary;
      return polar(b.speed_mps(), b.direction_deg() + (first ? 0.0 : b.angle_deg()));
    }
    case R::REGIME_NOT_SET:
      break;
  }
  return {0.0f, 0.0f};
}

namespace {
const erg::v1::WindRegime& regime_of(const erg::v1::JobSpec& spec, std::int64_t step,
                                     std::int64_t& since) {
  const erg::v1::WindRegime* regime = &spec.wind();
  since = 0;
  for (const auto& e : spec.events())
    if (e.has_wind() && e.step() <= step && e.step() >= since) {
      regime = &e.wind();
      since = e.step();
    }
  return *regime;
}
}  // namespace

Vec2 at_step(const erg::v1::JobSpec& spec, std::int64_t step) {
  std::int64_t since = 0;
  const auto& regime = regime_of(spec, step, since);
  const Vec2 a = regime_at(regime, step - since, step, spec.seed());
  if (!physics::physical(regime)) return a;
  // Physical speeds: u* (directly or by the law of the wall), and the model
  // wind is the 10 m wind over still sand for that u* (wind/physics.h).
  const physics::Sand s = physics::sand_of(spec);
  return static_cast<float>(physics::ustar_per_speed(regime, s) * physics::model_gain(s)) * a;
}

const erg::v1::WindRegime& regime_in_effect(const erg::v1::JobSpec& spec, std::int64_t step) {
  std::int64_t since = 0;
  return regime_of(spec, step, since);
}

double shear_velocity_at(const erg::v1::JobSpec& spec, std::int64_t step) {
  if (!physics::physical(spec)) return 0.0;
  return static_cast<double>(length(at_step(spec, step))) /
         physics::model_gain(physics::sand_of(spec));
}

}  // namespace erg::wind
