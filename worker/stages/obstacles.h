// SPDX-License-Identifier: Apache-2.0
// Obstacles ([BR04] 4, Benes and Roa 2004; [N24] 3.5 "object map"): rocks,
// buildings and roads, cells that hold no sand and are never eroded.
//
// A tile holds the obstacle height o >= 0 per cell (metres; o > 0 is an
// obstacle). Its effects, each at the stage it belongs to:
//   * wind: o is added to the terrain the wind sees (venturi, warping,
//     shadow), never to the sand or bedrock totals, so an obstacle shadows
//     the ground behind it as terrain of that height would [BR04 4.3];
//   * saltation: nothing is lifted from it (it holds no sand), and sand is
//     never transferred into it: a hop that meets an obstacle lands on the
//     last free cell of its path, the obstacle's windward border [BR04 4.1,
//     Fig. 4], where the usual deposition applies (what bounces is blocked
//     again at the next step). Sand accumulates on the windward side and
//     every unit stays accounted for;
//   * reptation and avalanching: no exchange with an obstacle cell; it is a
//     wall [BR04 4.2: "no material can be moved inside the obstacle"; N24 3.5:
//     "no avalanching is applied to them"].
#pragma once

#include "core/hd.h"
#include "core/units.h"

namespace erg::obstacles {

ERG_HD bool is_obstacle(float o) {
  return o > 0.0f;
}

// One shape of a job's obstacles (or of an obstacle event), in metres on the
// torus. A road is a chain of capsules, one per segment of its polyline.
enum Kind : int { kDisk = 0, kRect = 1, kCapsule = 2 };
struct Shape {
  int kind;
  double ax, ay;  // disk centre; rectangle's south-west corner; segment start
  double bx, by;  // rectangle size; segment end (not wrapped: a - b is the segment)
  double r;       // disk radius; half the road width
  float height_m;
  double lx_m, ly_m;  // domain extent (wrap)
};

ERG_HD double wrap_delta(double d, double period) {
  d = fmod(d, period);
  if (d >= 0.5 * period) d -= period;
  if (d < -0.5 * period) d += period;
  return d;
}

// Whether the point (px, py) (a cell centre) is inside the shape.
ERG_HD bool covers(const Shape& s, double px, double py) {
  const double dx = wrap_delta(px - s.ax, s.lx_m), dy = wrap_delta(py - s.ay, s.ly_m);
  if (s.kind == kDisk) return dx * dx + dy * dy <= s.r * s.r;
  if (s.kind == kRect) {
    double u = fmod(px - s.ax, s.lx_m), v = fmod(py - s.ay, s.ly_m);
    if (u < 0) u += s.lx_m;
    if (v < 0) v += s.ly_m;
    return u < s.bx && v < s.by;
  }
  // Capsule: distance from the segment a -> b (the point taken nearest to a
  // on the torus) at most r.
  const double sx = s.bx - s.ax, sy = s.by - s.ay;
  const double len2 = sx * sx + sy * sy;
  double t = len2 > 0.0 ? (dx * sx + dy * sy) / len2 : 0.0;
  t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
  const double ex = dx - t * sx, ey = dy - t * sy;
  return ex * ex + ey * ey <= s.r * s.r;
}

// An obstacle edit at the cell centred at (px, py): `remove` clears the cell;
// otherwise it takes the larger height and loses its sand on the ground and
// in the air (an obstacle holds none, [BR04 4]). Returns the units taken
// from the sand total (>= 0).
ERG_HD units_t edit_cell(const Shape& s, bool remove, double px, double py, float& o, units_t& sand,
                         units_t& airborne) {
  if (!covers(s, px, py)) return 0;
  if (remove) {
    o = 0.0f;
    return 0;
  }
  o = o < s.height_m ? s.height_m : o;  // max(o, height)
  const units_t gone = sand + airborne;
  sand = 0;
  airborne = 0;
  return gone;
}

// The obstacle's height in units, added to the exact block sums of the wind
// warping's coarse grid (every tile converts its own cells the same way).
ERG_HD units_t height_units(float o) {
  return floor_units(o * kUnitsPerMf);
}

// Avalanching height of a cell: an obstacle is a wall no neighbour's excess
// can reach (eq. 9 gives 0 towards it). Its own fraction is forced to 0.
inline constexpr float kWallM = 1.0e30f;
ERG_HD float avalanche_height(float h, float o) {
  return is_obstacle(o) ? kWallM : h;
}

// The path of a hop leaving local cell (x, y) with a shift of (dx, dy) cells
// (saltation::landing): the cells (x + round(t dx), y + round(t dy)) for
// t = j / n, j = 1..n, n = ceil(max(|dx|, |dy|)), a walk that visits every
// cell the hop crosses. Rounding depends only on the shift, never on where
// the tile starts, so every tiling walks the same cells. `end` is the last
// free cell before the first obstacle (the source when the first step is
// blocked), or the hop's nearest cell when nothing blocks it.
struct Path {
  bool blocked;
  int x, y;  // end
};
ERG_HD Path hop_path(const float* o_base, long pitch, int x, int y, float dx, float dy) {
  const float adx = dx < 0.0f ? -dx : dx, ady = dy < 0.0f ? -dy : dy;
  const int n = static_cast<int>(ceilf(max_of(adx, ady)));
  int px = x, py = y;
  for (int j = 1; j <= n; ++j) {
    const float t = static_cast<float>(j) / static_cast<float>(n);
    const int cx = x + static_cast<int>(floorf(t * dx + 0.5f));
    const int cy = y + static_cast<int>(floorf(t * dy + 0.5f));
    if (is_obstacle(o_base[static_cast<long>(cy) * pitch + cx])) return {true, px, py};
    px = cx;
    py = cy;
  }
  return {false, px, py};
}

// Where the part of a hop meant for cell (cx, cy) lands: that cell when it is
// free, else the end of the hop's path (free, and one of the four cells of
// the bilinear split when the path is not blocked) [BR04 4.1].
struct Cell {
  int x, y;
};
ERG_HD Cell receiver(const float* o_base, long pitch, int cx, int cy, const Path& path) {
  if (path.blocked || is_obstacle(o_base[static_cast<long>(cy) * pitch + cx]))
    return {path.x, path.y};
  return {cx, cy};
}

}  // namespace erg::obstacles
