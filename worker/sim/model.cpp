// SPDX-License-Identifier: Apache-2.0
#include "sim/model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/units.h"
#include "wind/physics.h"

namespace erg {

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}

Model make_model(const erg::v1::JobSpec& spec, int nx, int ny, int x0, int y0,
                 AvalancheRounds rounds) {
  const auto& m = spec.model();
  const double l = spec.domain().cell_size_m();
  Model md;
  md.seed = static_cast<std::uint64_t>(spec.seed());
  md.stochastic = spec.transport() == erg::v1::JobSpec::STOCHASTIC;
  md.venturi_k = static_cast<float>(m.venturi_k());
  md.warp.weight[0] = static_cast<float>(m.warp_large_weight());
  md.warp.weight[1] = static_cast<float>(m.warp_small_weight());
  md.warp.deviation[0] = static_cast<float>(m.warp_large_deviation());
  md.warp.deviation[1] = static_cast<float>(m.warp_small_deviation());
  md.warp.gradient_scale = static_cast<float>(m.warp_gradient_scale());

  const int gnx = static_cast<int>(spec.domain().nx()), gny = static_cast<int>(spec.domain().ny());
  // The coarse cells depend on the model's lengths only; validation makes
  // the domain a multiple of them.
  md.coarse =
      wind_warping::coarse_grid(gnx, gny, l, wind_warping::sigma_of_radius(m.warp_large_radius_m()),
                                wind_warping::sigma_of_radius(m.warp_small_radius_m()));
  if (gnx % md.coarse.cx != 0 || gny % md.coarse.cy != 0)
    throw std::invalid_argument("domain.nx and domain.ny must be multiples of " +
                                std::to_string(md.coarse.cx) +
                                " cells (the coarse grid of the wind warping)");

  md.shadow.steps = static_cast<int>(std::ceil(m.shadow_radius_m() / l - 1e-9));
  md.shadow.cell_m = static_cast<float>(l);
  md.shadow.tan_min = static_cast<float>(std::tan(m.shadow_angle_min_deg() * kDeg));
  md.shadow.tan_max = static_cast<float>(std::tan(m.shadow_angle_max_deg() * kDeg));
  md.shadow.steps = std::min(md.shadow.steps, wind_shadow::kMaxShadowSteps);  // validated: <= 128
  md.shadow.cubic = m.shadow_sampling() == erg::v1::ModelParameters::CUBIC;
  wind_shadow::finish(md.shadow);

  auto& e = md.echo;
  e.on = m.echo_dunes();
  e.steps = std::min(static_cast<int>(std::ceil(m.echo_reach_m() / l - 1e-9)),
                     wind_shadow::kMaxShadowSteps);  // validated: <= 128
  e.rise_per_cell = static_cast<float>(std::tan(m.echo_cliff_deg() * kDeg) * l);
  e.cell_m = static_cast<float>(l);
  e.gap_ratio = static_cast<float>(m.echo_gap_ratio());
  e.sticky_ratio = static_cast<float>(m.echo_sticky_ratio());
  e.stickiness = static_cast<float>(m.echo_stickiness());

  auto& s = md.saltation;
  s.slab_units = static_cast<float>(m.slab_m() * kUnitsPerM);
  s.hop_time_s = static_cast<float>(m.hop_time_s());
  s.max_hop_m = static_cast<float>(m.max_hop_m());
  s.cell_m = static_cast<float>(l);
  s.deposit_on_sand = static_cast<float>(m.deposit_on_sand());
  s.deposit_on_bedrock = static_cast<float>(m.deposit_on_bedrock());
  s.abrasion_k = static_cast<float>(m.abrasion_k());
  s.abrasion_threshold = m_to_units(m.abrasion_sand_threshold_m());
  s.stochastic = md.stochastic;
  s.erosion_k = static_cast<float>(m.echo_erosion_k());
  s.ustar_per_mps = 0.0f;
  s.ustar_t = 0.0f;
  s.inv_reference_shape = 0.0f;
  s.kawamura = false;
  s.slope_k = 0.0f;
  if (physics::physical(spec)) {
    const physics::Sand sand = physics::sand_of(spec);
    const double ut = physics::threshold(sand);
    s.ustar_per_mps = static_cast<float>(1.0 / physics::model_gain(sand));
    s.ustar_t = static_cast<float>(ut);
    s.inv_reference_shape =
        static_cast<float>(1.0 / physics::flux_shape(sand, sand.reference_excess * ut));
    s.kawamura = sand.law == erg::v1::PhysicalParameters::KAWAMURA_1951;
    s.slope_k = static_cast<float>(sand.slope_k);
    // The hop of the saturation length (Andreotti, Claudin & Pouliquen 2010),
    // resolved on the grid (physics::physical_hop_m).
    s.max_hop_m =
        static_cast<float>(physics::physical_hop_m(sand, m.deposit_on_sand(), l, m.max_hop_m()));
    // The shear stress over relief (Kroy, Sauermann & Herrmann 2002), on the
    // warping's coarse window, whose halo then covers its kernel too.
    md.shear.on = physics::shear_stress_on(spec);
    md.shear.a = static_cast<float>(sand.shear_a);
    md.shear.b = static_cast<float>(sand.shear_b);
    md.shear.radius = shear_stress::kernel_radius(sand.shear_radius_m, md.coarse.cx * l);
    md.shear.cx = md.coarse.cx;
    md.shear.cy = md.coarse.cy;
    md.shear.delta_m = md.coarse.cx * l;
    const int reach = std::max(md.shear.radius, shear_stress::kCorrectionRadius);
    md.coarse.halo_x = std::max(md.coarse.halo_x, reach + 2);
    md.coarse.halo_y = std::max(md.coarse.halo_y, reach + 2);
  }

  md.reptation_k = static_cast<float>(m.reptation_k());
  md.tan_l_sand = static_cast<float>(std::tan(m.repose_deg() * kDeg) * l);
  md.tan_l_vegetated = static_cast<float>(std::tan(m.repose_vegetated_deg() * kDeg) * l);
  md.tan_l_bedrock = static_cast<float>(std::tan(m.bedrock_repose_deg() * kDeg) * l);
  md.repose_isotropic = m.repose() == erg::v1::ModelParameters::ISOTROPIC;
  md.avalanche_iterations = static_cast<int>(m.avalanche_iterations());
  md.kc = static_cast<float>(m.avalanche_kc());
  md.kc_damped = static_cast<float>(m.avalanche_kc_damped());
  md.bedrock_iterations = static_cast<int>(m.bedrock_avalanche_iterations());
  md.bedrock_to_sand = m.bedrock_to_sand();
  md.time_step_days = m.time_step_days();
  md.rounds = rounds;

  TileGeom& t = md.tile;
  t.nx = nx;
  t.ny = ny;
  t.x0 = x0;
  t.y0 = y0;
  t.gnx = gnx;
  t.gny = gny;
  t.cell_m = static_cast<float>(l);
  t.halo = std::max({md.halo_shadow(), md.halo_saltation(), md.halo_avalanche() + 1, 2});
  t.pitch = padded_pitch(nx, t.halo);
  return md;
}

}  // namespace erg
