// SPDX-License-Identifier: Apache-2.0
// The sand and the wind in physical terms (docs/physical-units.md): the fluid
// threshold of Bagnold 1941, the saturated flux laws of Lettau & Lettau 1978
// and Kawamura 1951, the law of the wall, and how a physical wind drives the
// model. Used by the wind regime (a(t) from u*), the model (the lift's flux
// factor, stages/saltation.h), the calibration (sim/calibration.h) and the
// tests, so every number comes from one place.
#pragma once

#include <string>
#include <vector>

#include "erg/v1/job.pb.h"

namespace erg::physics {

// PhysicalParameters with their defaults (from the proto options) resolved.
struct Sand {
  double d = 0, rho_s = 0, rho = 0, packing = 0, g = 0, a = 0, kappa = 0;
  double reference_excess = 0;
  double saturation_length_m = 0;  // 0: 2.2 (rho_s / rho) d (saturation_length)
  double shear_a = 0, shear_b = 0, shear_radius_m = 0;  // stages/shear_stress.h
  double slope_k = 0;  // physics.hop_slope_deflection (stages/saltation.h)
  erg::v1::PhysicalParameters::FluxLaw law = erg::v1::PhysicalParameters::LETTAU_1978;
};
Sand sand_of(const erg::v1::JobSpec& spec);

// The saturation length of the flux: physics.saturation_length_m, or when 0
// L_sat = 2.2 (rho_s / rho) d, measured in wind tunnels and from the
// wavelength of emerging dunes (Andreotti, Claudin & Pouliquen 2010): 1.19 m
// for 0.25 mm quartz sand in sea-level air. Metres.
double saturation_length(const Sand& s);
// The hop of the physical modes: the model's airborne sand deposits a
// fraction beta (model.deposit_on_sand) at each landing, so its flux relaxes
// over hop / beta; the hop is beta L_sat, at least one cell (a shorter hop is
// not resolved: it would land mostly where it left) and at most max_hop_m.
double physical_hop_m(const Sand& s, double deposit_on_sand, double cell_m, double max_hop_m);

// Whether the job's wind speeds are physical (shear velocity or a wind at a
// height) rather than model units.
bool physical(const erg::v1::WindRegime& w);
bool physical(const erg::v1::JobSpec& spec);
// Whether the shear stress over relief (stages/shear_stress.h) runs: in the
// physical modes with physics.shear_stress_a > 0. The model, the resolution
// checks and the step warning all ask here.
bool shear_stress_on(const erg::v1::JobSpec& spec);

// Fluid threshold u_t = A sqrt((rho_s - rho) / rho g d) [Bagnold 1941 ch. 7], m/s.
double threshold(const Sand& s);
// Saturated mass flux (kg per metre of width per second) at shear velocity
// u*; 0 at or below the threshold.
double flux_mass(const Sand& s, double ustar);
// The same as a bulk flux: m^2/s of sand as it lies (packing * rho_s).
double flux_bulk(const Sand& s, double ustar);
// Name and formula of the law, for attributes and reports.
std::string law_name(const Sand& s);
// The law's dependence on u* alone, which the lift follows: u*^2 (u* - u_t)
// (Lettau) or (u* - u_t)(u* + u_t)^2 (Kawamura); 0 below u_t.
double flux_shape(const Sand& s, double ustar);

// Shear velocity of a regime's speed (speed_is): u* itself, or kappa U /
// ln(z / z0) for a wind at a height (z0 = 0 means d / 30). Linear in speed.
double ustar_per_speed(const erg::v1::WindRegime& w, const Sand& s);

// In the physical modes the model's high-altitude wind a(t) (which venturi,
// warping and shadow shape) is the 10 m wind over still sand (z0 = d / 30)
// for the regime's u*: |a| = u* ln(10 m / z0) / kappa. The surface wind then
// gives the local u* = |w| / model_gain: a speed-up of the wind is a speed-up
// of u*.
double model_gain(const Sand& s);

// Drift potentials of a set of winds (Fryberger & Dean 1979) with the flux
// law of `s` in place of their V^2 (V - V_t): each wind's bulk flux
// q = flux_bulk(u* = ustar_per_speed * speed) weighted by its share of the
// time. DP: the mean magnitude; RDP: the magnitude of the mean vector; RDD:
// its direction, degrees ccw from +x (towards). m^2/s of bulk sand.
struct WindShare {
  double direction_deg = 0;  // towards, ccw from +x
  double speed_mps = 0;      // in the regime's speed_is
  double weight = 0;         // share of the time (the weights sum to 1)
};
struct DriftPotential {
  double dp = 0, rdp = 0, rdd_deg = 0;
};
DriftPotential drift_potential(const Sand& s, double ustar_per_speed,
                               const std::vector<WindShare>& winds);

}  // namespace erg::physics
