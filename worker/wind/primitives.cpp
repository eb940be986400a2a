// SPDX-License-Identifier: Apache-2.0
#include "wind/primitives.h"

#include <algorithm>
#include <cmath>

#include "wind/regime.h"

namespace erg::wind {

namespace {
constexpr double kTwoPi = 6.283185307179586;

struct Placed {
  const erg::v1::WindPrimitive* w;
  std::int64_t origin;
};

// x into [0, period).
double wrap_into(double x, double period) {
  x = std::fmod(x, period);
  if (x < 0) x += period;
  return x < period ? x : 0.0;
}

// The cells within `reach_m` of a centre along one axis (conservative by a
// cell on each side): first cell and count, or the whole axis.
void span_of(double centre_m, double reach_m, double cell_m, int n, int& b0, int& w) {
  const double first = std::floor((centre_m - reach_m) / cell_m) - 1.0;
  const double count = std::ceil(2.0 * reach_m / cell_m) + 3.0;
  if (count >= n) {
    b0 = 0;
    w = n;
    return;
  }
  b0 = static_cast<int>(wrap_into(first, n));
  w = static_cast<int>(count);
}

wind_primitives::Primitive resolve(const erg::v1::JobSpec& spec, const Placed& pl,
                                   std::int64_t step, double env) {
  namespace wp = wind_primitives;
  const auto& w = *pl.w;
  wp::Primitive P;
  P.gnx = static_cast<int>(spec.domain().nx());
  P.gny = static_cast<int>(spec.domain().ny());
  P.cell_m = spec.domain().cell_size_m();
  P.lx_m = P.gnx * P.cell_m;
  P.ly_m = P.gny * P.cell_m;
  if (w.has_vortex()) {
    const auto& v = w.vortex();
    P.kind = wp::kVortex;
    P.cx_m = v.x_m();
    P.cy_m = v.y_m();
    P.radius_m = v.radius_m();
    P.exponent = v.falloff_exponent();
    // |d psi / dr| peaks at r = R with amp e^(-1/p) / R: amp = U R e^(1/p).
    const double sense = v.rotation() == erg::v1::Vortex::CLOCKWISE ? -1.0 : 1.0;
    P.amp = env * sense * v.peak_speed_mps() * v.radius_m() * std::exp(1.0 / P.exponent);
    P.cx_m = wrap_into(P.cx_m, P.lx_m);
    P.cy_m = wrap_into(P.cy_m, P.ly_m);
    const double reach = wp::kSupport * P.radius_m;
    span_of(P.cx_m, reach, P.cell_m, P.gnx, P.bx0, P.bw);
    span_of(P.cy_m, reach, P.cell_m, P.gny, P.by0, P.bh);
    return P;
  }
  const auto& t = w.turbulence();
  P.kind = wp::kTurbulence;
  P.cx_m = t.x_m();
  P.cy_m = t.y_m();
  P.region_m = t.has_radius_m() ? t.radius_m() : -1.0;
  P.falloff_m = t.falloff_m();
  // The lattice divides the domain (tileable): the nearest whole number of
  // wavelengths along each side.
  P.px = static_cast<int>(std::max(1.0, std::round(P.lx_m / t.wavelength_m())));
  P.py = static_cast<int>(std::max(1.0, std::round(P.ly_m / t.wavelength_m())));
  const double lambda = std::sqrt((P.lx_m / P.px) * (P.ly_m / P.py));
  P.amp = env * t.amplitude_mps() * lambda / wp::kNoiseRmsGradient;
  const double local = static_cast<double>(step - pl.origin - w.start_step());
  if (t.period_steps() > 0) {
    const double phase =
        kTwoPi * static_cast<double>((step - pl.origin - w.start_step()) % t.period_steps()) /
        static_cast<double>(t.period_steps());
    P.w1 = std::cos(phase);
    P.w2 = std::sin(phase);
  }
  const Vec2 d = direction(t.drift_direction_deg());
  P.shift_x_m = wrap_into(t.drift_m_per_step() * local * d.x, P.lx_m);
  P.shift_y_m = wrap_into(t.drift_m_per_step() * local * d.y, P.ly_m);
  P.cx_m = wrap_into(P.cx_m, P.lx_m);
  P.cy_m = wrap_into(P.cy_m, P.ly_m);
  if (P.region_m >= 0) {
    span_of(P.cx_m, P.region_m, P.cell_m, P.gnx, P.bx0, P.bw);
    span_of(P.cy_m, P.region_m, P.cell_m, P.gny, P.by0, P.bh);
  } else {
    P.bw = P.gnx;
    P.bh = P.gny;
  }
  const auto seed = static_cast<std::uint64_t>(spec.seed()) +
                    static_cast<std::uint64_t>(t.seed_offset()) * 0x9E3779B97F4A7C15ull;
  P.seed1 = static_cast<std::uint32_t>(seed ^ (seed >> 32)) ^ 0x5EEDC0DEu;
  P.seed2 = wp::hash3(P.seed1, 0x7u, 0x2545F491u);
  return P;
}
}  // namespace

double envelope(const erg::v1::WindPrimitive& w, std::int64_t origin, std::int64_t step) {
  const std::int64_t t = step - origin;
  if (t < w.start_step() || (w.has_end_step() && t >= w.end_step())) return 0.0;
  const double r = static_cast<double>(w.ramp_steps()) + 1.0;
  double a = static_cast<double>(t - w.start_step() + 1) / r;
  if (w.has_end_step()) a = std::min(a, static_cast<double>(w.end_step() - t) / r);
  return wind_primitives::smoothstep01(a);
}

std::vector<wind_primitives::Primitive> primitives_at(const erg::v1::JobSpec& spec,
                                                      std::int64_t step) {
  std::vector<Placed> placed;
  for (const auto& w : spec.wind_primitives()) placed.push_back({&w, 0});
  if (spec.events_size() > 0) {
    // Timeline order: by step, then file order.
    std::vector<int> order;
    for (int k = 0; k < spec.events_size(); ++k)
      if (spec.events(k).step() <= step) order.push_back(k);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return spec.events(a).step() < spec.events(b).step(); });
    for (int k : order) {
      const auto& e = spec.events(k);
      if (e.action_case() == erg::v1::Event::kWindPrimitive) {
        placed.push_back({&e.wind_primitive(), e.step()});
      } else if (e.action_case() == erg::v1::Event::kRemoveWindPrimitive) {
        const std::string& name = e.remove_wind_primitive();
        std::erase_if(placed, [&](const Placed& p) { return p.w->name() == name; });
      }
    }
  }
  std::vector<wind_primitives::Primitive> out;
  for (const auto& p : placed) {
    const double env = envelope(*p.w, p.origin, step);
    if (env > 0.0) out.push_back(resolve(spec, p, step, env));
  }
  return out;
}

std::vector<wind_primitives::Batch> batches(const std::vector<wind_primitives::Primitive>& p) {
  std::vector<wind_primitives::Batch> out;
  for (size_t k = 0; k < p.size(); ++k) {
    if (k % wind_primitives::kBatch == 0) out.emplace_back();
    wind_primitives::Batch& b = out.back();
    b.p[b.n++] = p[k];
  }
  return out;
}

}  // namespace erg::wind
