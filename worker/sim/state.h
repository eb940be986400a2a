// The exact state of one tile: what a checkpoint holds. Everything else
// (heights, wind, shadow, buffers) is derived from it each step.
#pragma once

#include <cstdint>

#include "core/field.h"
#include "core/units.h"

namespace erg {

struct TileState {
  TileGeom geom;
  Field<units_t> bedrock;   // b, units
  Field<units_t> sand;      // s >= 0, units, on the ground
  Field<units_t> airborne;  // saltating sand that bounced, units [N24 slab buffer]
  Field<float> vegetation;  // v in [0, 1]
  Field<float> resistance;  // r in [0, 1]
  Field<float> obstacles;   // obstacle height o >= 0, metres; o > 0: an obstacle [BR04]

  void allocate(const TileGeom& g) {
    geom = g;
    bedrock.reset(g);
    sand.reset(g);
    airborne.reset(g);
    vegetation.reset(g);
    resistance.reset(g);
    obstacles.reset(g);
  }
};

// Exact totals over the owned cells.
struct Totals {
  total_t sand = 0;      // on the ground
  total_t airborne = 0;  // in saltation
  total_t bedrock = 0;
  total_t all_sand() const { return sand + airborne; }
};

}  // namespace erg
