// SPDX-License-Identifier: Apache-2.0
// Timeline edits ([P19] 7.1): brushes that add or remove sand, raise or
// lower bedrock, and vegetation set in a region. Positions are in metres on
// the torus; distances wrap.
#pragma once

#include "core/hd.h"
#include "core/units.h"
#include "stages/obstacles.h"

namespace erg::events {

struct Brush {
  double x_m, y_m;    // centre
  double radius_m;    // outer radius
  double falloff_m;   // width of the smooth edge
  double height_m;    // at the centre; negative removes
  double lx_m, ly_m;  // domain extent (wrap)
};

struct Region {
  double x_m, y_m;           // rectangle corner, or disk centre
  double width_m, height_m;  // rectangle (radius_m < 0)
  double radius_m;           // disk (>= 0)
  float value;
  double lx_m, ly_m;
};

ERG_HD double wrap_delta(double d, double period) {
  d = fmod(d, period);
  if (d >= 0.5 * period) d -= period;
  if (d < -0.5 * period) d += period;
  return d;
}

// Brush weight in [0, 1] at a point: 1 inside radius - falloff, smoothstep to
// 0 at the radius.
ERG_HD double brush_weight(const Brush& b, double px, double py) {
  const double dx = wrap_delta(px - b.x_m, b.lx_m), dy = wrap_delta(py - b.y_m, b.ly_m);
  const double d = sqrt(dx * dx + dy * dy);
  if (d >= b.radius_m) return 0.0;
  const double inner = b.radius_m - b.falloff_m;
  if (d <= inner) return 1.0;
  double t = (b.radius_m - d) / b.falloff_m;
  return t * t * (3.0 - 2.0 * t);
}

// Units added at a cell (negative: removed), before any clamping.
ERG_HD units_t brush_units(const Brush& b, double px, double py) {
  const double w = brush_weight(b, px, py);
  if (w == 0.0) return 0;
  return static_cast<units_t>(llround(b.height_m * w * kUnitsPerM));
}

// The sand brush at one cell holding `sand` units under obstacle height `o`:
// never below bare ground, and nothing on an obstacle (it holds no sand,
// [BR04 4]).
ERG_HD units_t sand_brush_change(const Brush& b, double px, double py, units_t sand, float o) {
  units_t d = brush_units(b, px, py);
  if (d < -sand) d = -sand;              // never below bare ground
  if (obstacles::is_obstacle(o)) d = 0;  // obstacles hold no sand
  return d;
}

ERG_HD bool in_region(const Region& r, double px, double py) {
  if (r.radius_m >= 0) {
    const double dx = wrap_delta(px - r.x_m, r.lx_m), dy = wrap_delta(py - r.y_m, r.ly_m);
    return dx * dx + dy * dy <= r.radius_m * r.radius_m;
  }
  // Rectangle [x, x + w) x [y, y + h), wrapping.
  double dx = fmod(px - r.x_m, r.lx_m), dy = fmod(py - r.y_m, r.ly_m);
  if (dx < 0) dx += r.lx_m;
  if (dy < 0) dy += r.ly_m;
  return dx < r.width_m && dy < r.height_m;
}

}  // namespace erg::events
