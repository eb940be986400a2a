// SPDX-License-Identifier: Apache-2.0
#include "sim/resolution.h"

#include <cmath>
#include <sstream>
#include <utility>

#include "stages/saltation.h"
#include "stages/wind_warping.h"
#include "wind/physics.h"

namespace erg {

namespace {

// A number for people: 3 significant digits, no trailing zeros.
std::string num(double v) {
  std::ostringstream o;
  o.precision(3);
  o << v;
  return o.str();
}
// A count of steps: whole numbers in full (1001, not 1e+03).
std::string steps(double v) {
  return v == std::floor(v) && std::fabs(v) < 1e15 ? std::to_string(static_cast<long long>(v))
                                                   : num(v);
}
std::string metres(double v) {
  return num(v) + " m";
}
std::string percent(double v) {
  return num(std::round(100.0 * v)) + "%";
}

// What a length lost to the grid does, said once for every rule.
constexpr const char* kOnTheGrid = "on the grid, not only on the physics";

// The sentence's ending: the cell size at which the length is resolved.
std::string resolved_at(double finest_m) {
  return " (resolved at domain.cell_size_m <= " + metres(finest_m) + ")";
}

// The landing kernel's spread, 1/2 cell, is a quarter of a hop of 2 cells.
static_assert(saltation::kLandingVar == 0.25f && kHopResolvedCells == 2.0,
              "the hop's rule and its words assume a landing spread of 1/2 cell");

// A hop of `hop_m` (what the job asks for) landing on the 3 x 3 kernel.
void check_hop(const std::string& what, const std::string& field, double hop_m, double used_m,
               double l, std::vector<UnresolvedLength>& out) {
  if (hop_m <= 0 || hop_m >= kHopResolvedCells * l) return;
  UnresolvedLength u{what, field, hop_m, l, hop_m / kHopResolvedCells, ""};
  std::string effect;
  // physics::physical_hop_m raises a hop to one cell, or to max_hop_m when
  // that is shorter.
  if (used_m > hop_m)
    effect = "it is raised to " + metres(used_m) +
             (used_m >= l ? " (1 cell)" : " (model.max_hop_m)") + ", and ";
  u.warning =
      "the " + what + ", " + field + " = " + metres(hop_m) + ", is shorter than " +
      num(kHopResolvedCells) + " cells of " + metres(l) + " (domain.cell_size_m): " + effect +
      "the landing kernel spreads every hop by 1/2 cell (" + metres(0.5 * l) +
      "), more than a quarter of the hop, so the sand flux and the dune wavelength depend " +
      kOnTheGrid + resolved_at(u.finest_m);
  out.push_back(std::move(u));
}

// A reach of `reach_m` taken in whole cells of `cell_m` (ceil, as the
// stages do); `cells` says which cells ("cells of 4 m (domain.cell_size_m)").
void check_reach(const std::string& what, const std::string& field, double reach_m, double cell_m,
                 const std::string& cells, const std::string& consequence, double finest_m,
                 std::vector<UnresolvedLength>& out) {
  if (reach_m <= 0 || reach_m >= kReachResolvedCells * cell_m) return;
  const int n = static_cast<int>(std::ceil(reach_m / cell_m - 1e-9));
  UnresolvedLength u{what, field, reach_m, cell_m, finest_m, ""};
  u.warning = "the " + what + ", " + field + " = " + metres(reach_m) + ", is shorter than " +
              num(kReachResolvedCells) + " " + cells + ": it is taken as " + std::to_string(n) +
              " whole cell" + (n == 1 ? "" : "s") + " (" + metres(n * cell_m) + ", " +
              percent(n * cell_m / reach_m - 1.0) +
              " longer); rounding to whole cells may lengthen a reach under " +
              num(kReachResolvedCells) + " cells by more than a quarter, so " + consequence + " " +
              kOnTheGrid + (finest_m > 0 ? resolved_at(finest_m) : "");
  out.push_back(std::move(u));
}

}  // namespace

std::vector<UnresolvedLength> unresolved_lengths(const erg::v1::JobSpec& spec) {
  std::vector<UnresolvedLength> out;
  const auto& m = spec.model();
  const double l = spec.domain().cell_size_m();
  if (!(l > 0)) return out;

  // The hop (stages/saltation.h, landing()): in the physical modes
  // deposit_on_sand x the saturation length (physics::physical_hop_m), in
  // model units |w| hop_time_s, at most max_hop_m: the longest hop.
  if (physics::physical(spec)) {
    const physics::Sand sand = physics::sand_of(spec);
    const double lsat_hop = m.deposit_on_sand() * physics::saturation_length(sand);
    const double used = physics::physical_hop_m(sand, m.deposit_on_sand(), l, m.max_hop_m());
    if (lsat_hop <= m.max_hop_m())
      check_hop("saltation hop",
                "model.deposit_on_sand x the saturation length (physics.saturation_length_m) = " +
                    num(m.deposit_on_sand()) + " x " + metres(physics::saturation_length(sand)),
                lsat_hop, used, l, out);
    else
      check_hop("saltation hop", "model.max_hop_m", m.max_hop_m(), used, l, out);
  } else if (m.hop_time_s() > 0) {
    check_hop("longest saltation hop", "model.max_hop_m", m.max_hop_m(), m.max_hop_m(), l, out);
  }

  // The wind shadow marches N_s = ceil(R_s / l) cells upwind [N24 eq. 4].
  check_reach("wind shadow's reach", "model.shadow_radius_m", m.shadow_radius_m(), l,
              "cells of " + metres(l) + " (domain.cell_size_m)",
              "the sheltered lee of a dune and the dunes' spacing depend",
              m.shadow_radius_m() / kReachResolvedCells, out);
  // Echo dunes look for a cliff ceil(reach / l) cells upwind.
  if (m.echo_dunes())
    check_reach("echo dunes' reach", "model.echo_reach_m", m.echo_reach_m(), l,
                "cells of " + metres(l) + " (domain.cell_size_m)", "where echo dunes form depends",
                m.echo_reach_m() / kReachResolvedCells, out);

  // The wind warping's Gaussians (stages/wind_warping.h): coarse cells of at
  // most sigma / 4, never narrower than one cell.
  const std::pair<const char*, double> radii[] = {
      {"model.warp_large_radius_m", m.warp_large_radius_m()},
      {"model.warp_small_radius_m", m.warp_small_radius_m()}};
  for (const auto& [field, radius] : radii) {
    const double sigma = wind_warping::sigma_of_radius(radius);
    if (!(sigma > 0) || sigma >= kSigmaResolvedCells * l) continue;
    UnresolvedLength u{"wind-warping smoothing", field, radius, l, sigma / kSigmaResolvedCells, ""};
    u.warning = std::string("the wind-warping smoothing, ") + field + " = " + metres(radius) +
                " (sigma = radius / 2 = " + metres(sigma) + "), has " + num(sigma / l) +
                " cells per sigma at " + metres(l) + " cells (domain.cell_size_m), fewer than " +
                num(kSigmaResolvedCells) +
                ": the smoothed slope the wind turns along is off by up to (l / sigma)^2 / 6 = " +
                num(100.0 * (l / sigma) * (l / sigma) / 6.0) +
                "%, so the wind's deflection by dunes and the dune forms depend " + kOnTheGrid +
                resolved_at(u.finest_m);
    out.push_back(std::move(u));
  }

  // The shear-stress kernel, on the warping's coarse cells (sim/model.cpp).
  if (physics::shear_stress_on(spec)) {
    const physics::Sand sand = physics::sand_of(spec);
    if (m.warp_large_radius_m() > 0 && m.warp_small_radius_m() > 0) {
      const int c =
          wind_warping::coarse_factor_of_radii(l, m.warp_large_radius_m(), m.warp_small_radius_m());
      // With one fine cell per coarse cell a finer grid shrinks the coarse
      // cell with it; with more, the coarse cell is set by the warping's
      // radii, not by domain.cell_size_m.
      check_reach("shear-stress kernel's reach", "physics.shear_stress_radius_m",
                  sand.shear_radius_m, c * l,
                  "coarse cells of " + metres(c * l) + " (the wind warping's, " +
                      std::to_string(c) + " x " + std::to_string(c) + " cells of " + metres(l) +
                      ")",
                  "the wind's speed-up over dunes and the dune forms depend",
                  c == 1 ? sand.shear_radius_m / kReachResolvedCells : 0.0, out);
    }
  }
  return out;
}

std::string step_warning(const erg::v1::JobSpec& spec) {
  const double l = spec.domain().cell_size_m();
  const double slab = spec.model().slab_m();
  if (!(l > 0) || !physics::shear_stress_on(spec)) return "";
  const double a = physics::sand_of(spec).shear_a;
  const double largest = kSlabPerCellWithStress * l;
  if (slab <= largest * (1 + 1e-9)) return "";
  return "the step's lift, model.slab_m = " + metres(slab) + ", is more than 1/" +
         num(1.0 / kSlabPerCellWithStress) + " of the cell (domain.cell_size_m = " + metres(l) +
         "): with the shear stress over relief on (physics.shear_stress_a = " + num(a) +
         "), windward faces steepen, dunes calve and spread with the step, not only with the "
         "physics (they stop at model.slab_m <= " +
         metres(largest) + ", with run.steps raised to cover the same time)";
}

std::vector<std::string> wind_period_warnings(const erg::v1::JobSpec& spec) {
  std::vector<std::string> out;
  const auto check = [&out](const erg::v1::WindRegime& w, const std::string& field) {
    if (!w.has_bidirectional()) return;
    const auto& b = w.bidirectional();
    const double p = static_cast<double>(b.period_steps());
    const double n = b.flux_ratio();
    if (p >= 1.0 + n) return;
    // The secondary's share of a period, p / (1 + N) steps, is under one
    // step: it blows one step in a fraction p / (1 + N) of the periods.
    out.push_back(field + ".period_steps = " + steps(p) + " is shorter than 1 + " + field +
                  ".flux_ratio = " + steps(1.0 + n) +
                  " steps: the secondary wind cannot blow in every period, so it blows one step "
                  "in about " +
                  percent(p / (1.0 + n)) +
                  " of the periods and the two winds alternate about every " + steps(1.0 + n) +
                  " steps, not every " + steps(p) +
                  " (the flux ratio is still exact over the long run; period_steps >= " +
                  steps(std::ceil(1.0 + n)) + " keeps both winds in every period)");
  };
  check(spec.wind(), "wind.bidirectional");
  for (int i = 0; i < spec.events_size(); ++i)
    if (spec.events(i).has_wind())
      check(spec.events(i).wind(), "events[" + std::to_string(i) + "].wind.bidirectional");
  return out;
}

std::vector<std::string> resolution_warnings(const erg::v1::JobSpec& spec) {
  std::vector<std::string> out;
  for (auto& u : unresolved_lengths(spec)) out.push_back(std::move(u.warning));
  if (auto w = step_warning(spec); !w.empty()) out.push_back(std::move(w));
  for (auto& w : wind_period_warnings(spec)) out.push_back(std::move(w));
  return out;
}

}  // namespace erg
