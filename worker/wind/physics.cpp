// SPDX-License-Identifier: Apache-2.0
#include "wind/physics.h"

#include <algorithm>
#include <cmath>

namespace erg::physics {

namespace {
// Bagnold's reference grain of the sqrt(d / D) scaling (Lettau & Lettau 1978).
constexpr double kBagnoldD = 0.00025;
constexpr double kLettauC = 4.2;     // Lettau & Lettau 1978
constexpr double kKawamuraK = 2.78;  // Kawamura 1951
}  // namespace

Sand sand_of(const erg::v1::JobSpec& spec) {
  // apply_defaults fills physics in the physical modes; a job in model units
  // has none, and then the proto's defaults are read field by field.
  erg::v1::PhysicalParameters p = spec.physics();
  const auto* d = p.GetDescriptor();
  const auto* r = p.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const auto* f = d->field(i);
    const auto& o = f->options().GetExtension(erg::v1::spec);
    if (f->has_presence() && !r->HasField(p, f) && o.has_default_value() &&
        f->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_DOUBLE)
      r->SetDouble(&p, f, o.default_value());
  }
  Sand s;
  s.d = p.grain_diameter_m();
  s.rho_s = p.grain_density_kg_m3();
  s.rho = p.air_density_kg_m3();
  s.packing = p.packing_fraction();
  s.g = p.gravity_m_s2();
  s.a = p.threshold_a();
  s.kappa = p.von_karman();
  s.reference_excess = p.reference_excess();
  s.saturation_length_m = p.saturation_length_m();
  s.shear_a = p.shear_stress_a();
  s.shear_b = p.shear_stress_b();
  s.shear_radius_m = p.shear_stress_radius_m();
  s.slope_k = p.hop_slope_deflection();
  s.law = p.flux_law() == erg::v1::PhysicalParameters::KAWAMURA_1951
              ? erg::v1::PhysicalParameters::KAWAMURA_1951
              : erg::v1::PhysicalParameters::LETTAU_1978;
  return s;
}

bool physical(const erg::v1::WindRegime& w) {
  return w.speed_is() == erg::v1::WindRegime::SHEAR_VELOCITY ||
         w.speed_is() == erg::v1::WindRegime::WIND_AT_HEIGHT;
}
bool physical(const erg::v1::JobSpec& spec) {
  return physical(spec.wind());
}

bool shear_stress_on(const erg::v1::JobSpec& spec) {
  return physical(spec) && sand_of(spec).shear_a > 0.0;
}

double saturation_length(const Sand& s) {
  constexpr double kAndreotti = 2.2;  // Andreotti, Claudin & Pouliquen 2010
  return s.saturation_length_m > 0 ? s.saturation_length_m : kAndreotti * s.rho_s / s.rho * s.d;
}

double physical_hop_m(const Sand& s, double deposit_on_sand, double cell_m, double max_hop_m) {
  const double hop = deposit_on_sand * saturation_length(s);
  return std::min(std::max(hop, cell_m), max_hop_m);
}

double threshold(const Sand& s) {
  return s.a * std::sqrt((s.rho_s - s.rho) / s.rho * s.g * s.d);
}

double flux_shape(const Sand& s, double ustar) {
  const double ut = threshold(s);
  if (ustar <= ut) return 0.0;
  if (s.law == erg::v1::PhysicalParameters::KAWAMURA_1951)
    return (ustar - ut) * (ustar + ut) * (ustar + ut);
  return ustar * ustar * (ustar - ut);
}

double flux_mass(const Sand& s, double ustar) {
  const double pre = s.law == erg::v1::PhysicalParameters::KAWAMURA_1951
                         ? kKawamuraK * s.rho / s.g
                         : kLettauC * std::sqrt(s.d / kBagnoldD) * s.rho / s.g;
  return pre * flux_shape(s, ustar);
}

double flux_bulk(const Sand& s, double ustar) {
  return flux_mass(s, ustar) / (s.packing * s.rho_s);
}

std::string law_name(const Sand& s) {
  return s.law == erg::v1::PhysicalParameters::KAWAMURA_1951
             ? "Kawamura 1951: q = 2.78 rho/g (u* - u_t)(u* + u_t)^2"
             : "Lettau & Lettau 1978: q = 4.2 sqrt(d/0.25mm) rho/g u*^2 (u* - u_t)";
}

double ustar_per_speed(const erg::v1::WindRegime& w, const Sand& s) {
  if (w.speed_is() != erg::v1::WindRegime::WIND_AT_HEIGHT) return 1.0;
  const double z0 = w.roughness_m() > 0 ? w.roughness_m() : s.d / 30.0;
  // height_m >= 0.01 m and z0 <= 1 m are validated, and height_m > z0.
  return s.kappa / std::log(w.height_m() / z0);
}

DriftPotential drift_potential(const Sand& s, double ustar_per_speed,
                               const std::vector<WindShare>& winds) {
  constexpr double kPi = 3.14159265358979323846;
  DriftPotential d;
  double rx = 0, ry = 0;
  for (const WindShare& w : winds) {
    const double q = w.weight * flux_bulk(s, ustar_per_speed * w.speed_mps);
    d.dp += q;
    rx += q * std::cos(w.direction_deg * kPi / 180);
    ry += q * std::sin(w.direction_deg * kPi / 180);
  }
  d.rdp = std::hypot(rx, ry);
  d.rdd_deg = std::atan2(ry, rx) * 180 / kPi;
  return d;
}

double model_gain(const Sand& s) {
  return std::log(10.0 / (s.d / 30.0)) / s.kappa;
}

}  // namespace erg::physics
