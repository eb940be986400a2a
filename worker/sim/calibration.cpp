// SPDX-License-Identifier: Apache-2.0
#include "sim/calibration.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <vector>

#include "core/units.h"
#include "job/spec.h"
#include "sim/simulation.h"
#include "stages/wind_warping.h"
#include "wind/physics.h"
#include "wind/regime.h"

namespace erg {

namespace {

constexpr int kCells = 64;          // the measuring torus: 64 x 64 cells
constexpr double kSandDepthM = 10;  // thick enough never to run out
constexpr double kSteady = 1e-9;    // airborne sand left from the first step

// The measuring job: the job's cell size, model and physics; a flat bed of
// thick sand whose surface is at 0 m (the venturi datum); one constant wind.
erg::v1::JobSpec flat_bed_job(const erg::v1::JobSpec& spec, double ustar, double direction_deg) {
  erg::v1::JobSpec j;
  j.set_name("calibration");
  j.set_seed(spec.seed());
  // Expected transport: the stochastic mode draws the same expected amounts
  // [P19 5.1], so its flux is that of the expected mode, without noise.
  j.set_transport(erg::v1::JobSpec::EXPECTED);
  *j.mutable_model() = spec.model();
  *j.mutable_physics() = spec.physics();
  j.mutable_model()->set_echo_dunes(false);
  // Reptation and avalanching move sand down slopes only ([N24] eqs. 6-11):
  // nothing on the steady flat bed. Off, so that the step of the
  // measurement (the emptied half stands higher than the full half by the
  // step's lift) does not send sand back across the line: that artefact
  // grows with the lift squared, against a crossing that grows with the
  // lift times the hop, so it reached 7% of the flux at 3 u_t with the
  // one-cell hop of the saturation length (docs/physical-units.md).
  j.mutable_model()->set_reptation_k(0);
  j.mutable_model()->set_avalanche_iterations(0);
  j.mutable_model()->set_bedrock_avalanche_iterations(0);
  // At least one wind-warping coarse cell (wide at very fine cells): the
  // torus must be a multiple of it (stages/wind_warping.h, coarse_factor).
  const auto& m = spec.model();
  const long long cells = std::max<long long>(
      kCells, wind_warping::coarse_factor_of_radii(
                  spec.domain().cell_size_m(), m.warp_large_radius_m(), m.warp_small_radius_m()));
  j.mutable_domain()->set_nx(cells);
  j.mutable_domain()->set_ny(cells);
  j.mutable_domain()->set_cell_size_m(spec.domain().cell_size_m());
  j.mutable_layers()->mutable_bedrock()->set_constant(-kSandDepthM);
  j.mutable_layers()->mutable_sand()->set_constant(kSandDepthM);
  auto* w = j.mutable_wind();
  w->set_speed_is(erg::v1::WindRegime::SHEAR_VELOCITY);
  w->mutable_constant()->set_speed_mps(ustar);
  w->mutable_constant()->set_direction_deg(direction_deg);
  j.mutable_run()->set_steps(0);
  job::apply_defaults(j);
  return j;
}

// Steps until the airborne sand of the first step has decayed below kSteady:
// a fraction 1 - beta of it bounces every step (beta = deposit_on_sand).
int spinup_steps(const erg::v1::JobSpec& spec) {
  const double bounce = 1.0 - spec.model().deposit_on_sand();
  if (bounce <= 0.0) return 2;
  const int n = static_cast<int>(std::ceil(std::log(kSteady) / std::log(bounce)));
  return std::clamp(n, 2, 4000);
}

// Sand (units) in the half of the torus that was emptied, after one step.
// axis 0: cells with x >= n/2 (or x < n/2 when the wind blows towards -x,
// so that it is always the half downwind of a line); axis 1 the same in y.
double crossing(const io::Checkpoint& steady, int axis, bool downwind_positive, double cell_m) {
  io::Checkpoint c = steady;
  const int n = c.nx;
  const auto in_half = [&](int x, int y) {
    const int k = axis == 0 ? x : y;
    return downwind_positive ? k >= n / 2 : k < n / 2;
  };
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      if (in_half(x, y)) {
        const size_t i = static_cast<size_t>(y) * n + x;
        c.units[fields::kBedrock][i] += c.units[fields::kSand][i];  // the surface stays level
        c.units[fields::kSand][i] = 0;
        c.units[fields::kAirborne][i] = 0;
      }
  RunOptions opt;
  opt.backend = BackendKind::kCpu;
  opt.threads = 1;
  Simulation sim(c, opt);
  sim.step();
  const io::Checkpoint after = sim.checkpoint();
  total_t units = 0;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      if (in_half(x, y)) {
        const size_t i = static_cast<size_t>(y) * n + x;
        units += after.units[fields::kSand][i] + after.units[fields::kAirborne][i];
      }
  // Volume per metre of width: sum(h) l^2 / (n l).
  return static_cast<double>(units) * kUnitM * cell_m / n;
}

}  // namespace

FlatBedFlux measure_flat_bed_flux(const erg::v1::JobSpec& spec, double ustar,
                                  double direction_deg) {
  const erg::v1::JobSpec j = flat_bed_job(spec, ustar, direction_deg);
  RunOptions opt;
  opt.backend = BackendKind::kCpu;
  opt.threads = 1;
  FlatBedFlux f;
  f.spinup_steps = spinup_steps(spec);
  io::Checkpoint steady;
  {
    Simulation sim(j, "", opt);
    for (int k = 0; k < f.spinup_steps; ++k) sim.step();
    steady = sim.checkpoint();
  }
  const double l = spec.domain().cell_size_m();
  const double r = direction_deg * 3.14159265358979323846 / 180.0;
  const double cx = std::cos(r), cy = std::sin(r);
  // A component of under 1e-6 of the wind crosses no line: not measured.
  if (std::fabs(cx) > 1e-6) f.qx = std::copysign(crossing(steady, 0, cx > 0, l), cx);
  if (std::fabs(cy) > 1e-6) f.qy = std::copysign(crossing(steady, 1, cy > 0, l), cy);
  return f;
}

Calibration calibrate(const erg::v1::JobSpec& spec) {
  Calibration c;
  if (!physics::physical(spec)) {
    c.dt_s = spec.model().time_step_days() * 86400.0;
    return c;
  }
  const physics::Sand s = physics::sand_of(spec);
  c.physical = true;
  c.ustar_t = physics::threshold(s);
  c.ustar_ref = s.reference_excess * c.ustar_t;
  c.law = physics::law_name(s);
  const FlatBedFlux f = measure_flat_bed_flux(spec, c.ustar_ref, 0.0);
  c.q_model_m2_step = f.qx;
  c.spinup_steps = f.spinup_steps;
  c.q_law_m2_s = physics::flux_bulk(s, c.ustar_ref);
  c.dt_s = c.q_model_m2_step / c.q_law_m2_s;
  return c;
}

Drift wind_drift(const erg::v1::JobSpec& spec, const Calibration& c, int steps) {
  constexpr double kPi = 3.14159265358979323846;
  Drift d;
  d.steps = steps;
  const physics::Sand s = physics::sand_of(spec);
  if (spec.wind().has_rose()) {
    std::vector<physics::WindShare> winds;
    for (const auto& e : spec.wind().rose().entries())
      winds.push_back({e.direction_deg(), e.speed_mps(), e.probability()});
    const physics::DriftPotential p =
        physics::drift_potential(s, physics::ustar_per_speed(spec.wind(), s), winds);
    d.law_dp = p.dp;
    d.law_rdp = p.rdp;
    d.law_rdd_deg = p.rdd_deg;
  }
  std::map<std::pair<float, float>, FlatBedFlux> measured;
  double sx = 0, sy = 0;
  for (int step = 0; step < steps; ++step) {
    const Vec2 a = wind::at_step(spec, step);
    auto it = measured.find({a.x, a.y});
    if (it == measured.end()) {
      const double ustar = wind::shear_velocity_at(spec, step);
      const double dir = std::atan2(a.y, a.x) * 180 / kPi;
      it =
          measured.emplace(std::make_pair(a.x, a.y), measure_flat_bed_flux(spec, ustar, dir)).first;
    }
    const double qx = it->second.qx / c.dt_s, qy = it->second.qy / c.dt_s;
    d.sim_dp += std::hypot(qx, qy) / steps;
    sx += qx / steps;
    sy += qy / steps;
  }
  d.winds = static_cast<int>(measured.size());
  d.sim_rdp = std::hypot(sx, sy);
  d.sim_rdd_deg = std::atan2(sy, sx) * 180 / kPi;
  return d;
}

std::string describe_units(const erg::v1::JobSpec& spec) {
  std::ostringstream o;
  o.precision(4);
  if (!physics::physical(spec)) {
    o << "wind speeds in model units (wind.speed_is = MODEL): speed_mps is the model's "
         "high-altitude wind, no transport threshold; a step is model.time_step_days = "
      << spec.model().time_step_days() << " days, a label (not measured)";
    return o.str();
  }
  const physics::Sand s = physics::sand_of(spec);
  const Calibration c = calibrate(spec);
  o << "wind speeds in physical units (wind.speed_is = "
    << (spec.wind().speed_is() == erg::v1::WindRegime::SHEAR_VELOCITY ? "SHEAR_VELOCITY"
                                                                      : "WIND_AT_HEIGHT")
    << "); grains d = " << s.d * 1e3 << " mm, rho_s = " << s.rho_s
    << " kg/m^3, bulk density = " << s.packing * s.rho_s << " kg/m^3\n"
    << "fluid threshold u_t = " << c.ustar_t << " m/s (Bagnold 1941, A = " << s.a << "); flux law "
    << c.law << "\n"
    << "calibration: flat-bed flux at u* = " << c.ustar_ref << " m/s measured " << c.q_model_m2_step
    << " m^2/step against the law's " << c.q_law_m2_s * 3.15576e7
    << " m^2/yr: one step = " << c.dt_s << " s = " << c.dt_s / 86400.0 << " days ("
    << 3.15576e7 / c.dt_s << " steps per year); model.time_step_days is not used";
  return o.str();
}

}  // namespace erg
