// SPDX-License-Identifier: Apache-2.0
// erg calibrate JOB.json: the physical-units measurements of a job as JSON
// (sim/calibration.h, docs/physical-units.md): the time per step, the
// flat-bed flux against the flux law over a range of u* / u_t, and the drift
// of the job's wind regime against Fryberger & Dean's DP, RDP and RDD.
// erg validate reads it.
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "job/spec.h"
#include "sim/calibration.h"
#include "wind/physics.h"

namespace erg::client {

int cmd_calibrate(const std::vector<std::string>& args) {
  std::string path;
  std::vector<double> ratios = {1.1, 1.25, 1.5, 2.0, 2.5, 3.0};
  int drift_steps = 20000;
  try {
    for (size_t i = 0; i < args.size(); ++i) {
      if (args[i] == "--ratios" && i + 1 < args.size()) {
        ratios.clear();
        std::istringstream in(args[++i]);
        for (std::string r; std::getline(in, r, ',');) {
          const double v = std::stod(r);
          if (!(v > 0 && v <= 100)) throw std::invalid_argument("--ratios: " + r);
          ratios.push_back(v);
        }
      } else if (args[i] == "--drift-steps" && i + 1 < args.size()) {
        drift_steps = std::stoi(args[++i]);
        if (drift_steps < 1 || drift_steps > 10000000)
          throw std::invalid_argument("--drift-steps must be in [1, 1e7]");
      } else if (path.empty() && !args[i].empty() && args[i][0] != '-') {
        path = args[i];
      } else {
        throw std::invalid_argument("unexpected argument '" + args[i] + "'");
      }
    }
    if (path.empty()) throw std::invalid_argument("JOB.json is required");
  } catch (const std::exception& e) {
    std::cerr << "erg calibrate: " << e.what()
              << "\nusage: erg calibrate JOB.json [--ratios R,R,...] [--drift-steps N]\n";
    return 2;
  }
  try {
    const auto spec = erg::job::load_job_file(path);
    if (!physics::physical(spec)) {
      std::cerr << "erg calibrate: " << path
                << ": the wind is in model units (wind.speed_is = MODEL); there is nothing to "
                   "measure: a step is model.time_step_days\n";
      return 2;
    }
    const physics::Sand s = physics::sand_of(spec);
    const Calibration c = calibrate(spec);
    std::ostringstream o;
    o.precision(9);
    o << "{\"dt_s\": " << c.dt_s << ", \"threshold_mps\": " << c.ustar_t
      << ", \"reference_mps\": " << c.ustar_ref
      << ", \"model_flux_m2_per_step\": " << c.q_model_m2_step
      << ", \"law_flux_m2_per_s\": " << c.q_law_m2_s << ", \"spinup_steps\": " << c.spinup_steps
      << ", \"law\": \"" << c.law << "\",\n"
      << " \"flux\": [";
    for (size_t k = 0; k < ratios.size(); ++k) {
      const double ustar = ratios[k] * c.ustar_t;
      const FlatBedFlux f = measure_flat_bed_flux(spec, ustar, 0.0);
      o << (k ? ",\n  " : "\n  ") << "{\"ratio\": " << ratios[k] << ", \"ustar_mps\": " << ustar
        << ", \"model_m2_per_step\": " << f.qx << ", \"sim_m2_per_s\": " << f.qx / c.dt_s
        << ", \"law_m2_per_s\": " << physics::flux_bulk(s, ustar) << "}";
    }
    const Drift d = wind_drift(spec, c, drift_steps);
    o << "],\n \"drift\": {\"steps\": " << d.steps << ", \"winds\": " << d.winds
      << ", \"rose\": " << (spec.wind().has_rose() ? "true" : "false")
      << ", \"law_dp_m2_per_s\": " << d.law_dp << ", \"law_rdp_m2_per_s\": " << d.law_rdp
      << ", \"law_rdd_deg\": " << d.law_rdd_deg << ", \"sim_dp_m2_per_s\": " << d.sim_dp
      << ", \"sim_rdp_m2_per_s\": " << d.sim_rdp << ", \"sim_rdd_deg\": " << d.sim_rdd_deg
      << "}}\n";
    std::cout << o.str();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "erg: invalid job:\n" << e.what() << "\n";
    return 2;
  }
}

}  // namespace erg::client
