// SPDX-License-Identifier: Apache-2.0
// The time a step represents, measured (docs/physical-units.md).
//
// In the physical modes (WindRegime.speed_is) the model's sand flux over a
// flat sand bed is measured at job start: a small torus of thick flat sand
// (the job's cell size, model and physics parameters, no relief, vegetation,
// obstacles or events) is blown by a constant reference wind u_ref =
// physics.reference_excess * u_t until its airborne sand is steady; then one
// half of the torus is emptied (its surface kept level) and one more step is
// run: the sand found in that half is what crossed the line into it, per
// metre of width: q_model in m^2 of bulk sand per step. The flux law gives
// q_law(u_ref) in m^2/s, and a step is dt = q_model / q_law seconds.
//
// The measurement runs on the CPU backend with one thread, so it is the same
// number on every machine, backend, thread count, tiling and restart; it is
// repeated (a few milliseconds) whenever a job starts or resumes, so it is
// always that of the job's current parameters.
#pragma once

#include <string>

#include "erg/v1/job.pb.h"

namespace erg {

struct Calibration {
  bool physical = false;       // false: model units, dt from model.time_step_days
  double dt_s = 0;             // physical time of one step, s
  double ustar_t = 0;          // fluid threshold u_t, m/s
  double ustar_ref = 0;        // reference u*, m/s
  double q_model_m2_step = 0;  // measured flat-bed flux at u_ref, m^2 per step
  double q_law_m2_s = 0;       // the law's bulk flux at u_ref, m^2/s
  int spinup_steps = 0;        // steps of the measurement before the crossing step
  std::string law;             // name and formula
};

// Flat-bed flux of the model (m^2 of bulk sand per metre of width per
// step) under a constant shear velocity `ustar` blowing towards
// `direction_deg`, across lines of constant x (component x) and constant y
// (component y). `spec` is a defaults-filled, validated physical-mode job.
struct FlatBedFlux {
  double qx = 0, qy = 0;
  int spinup_steps = 0;
};
FlatBedFlux measure_flat_bed_flux(const erg::v1::JobSpec& spec, double ustar, double direction_deg);

// The calibration of a defaults-filled, validated job (model units: dt from
// model.time_step_days, nothing measured).
Calibration calibrate(const erg::v1::JobSpec& spec);

// Drift of a job's wind regime (Fryberger & Dean 1979) per unit time, in
// m^2/s of bulk sand: from the flux law with the rose's probabilities
// (law_*; a rose only, else 0) and simulated: the regime's own wind at each
// of `steps` steps, each distinct wind's flat-bed flux measured once
// (measure_flat_bed_flux) and divided by the calibrated dt (sim_*).
// DP: the mean magnitude; RDP: the magnitude of the mean vector; RDD: its
// direction, degrees ccw from +x (towards).
struct Drift {
  double law_dp = 0, law_rdp = 0, law_rdd_deg = 0;
  double sim_dp = 0, sim_rdp = 0, sim_rdd_deg = 0;
  int steps = 0, winds = 0;  // steps drawn, distinct winds measured
};
Drift wind_drift(const erg::v1::JobSpec& spec, const Calibration& c, int steps);

// Lines for `erg check`: which mode the job is in, and in the physical
// modes the threshold, the law and the measured time per step.
std::string describe_units(const erg::v1::JobSpec& spec);

}  // namespace erg
