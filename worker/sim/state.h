// SPDX-License-Identifier: Apache-2.0
// The exact state of one tile: what a checkpoint holds. Everything else
// (heights, wind, shadow, buffers) is derived from it each step. Its fields
// are the state fields of the registry (core/fields.h).
#pragma once

#include <cstdint>

#include "core/field.h"
#include "core/fields.h"
#include "core/units.h"

namespace erg {

// units[id] for integer fields, reals[id] for float ones; only the state
// fields are allocated.
struct TileState : fields::ByField<Field> {
  TileGeom geom;

  void allocate(const TileGeom& g) {
    geom = g;
    fields::each([&](fields::Id id, const fields::Info& f) {
      if (!f.state) return;
      if (f.type == fields::Type::kUnits)
        units[id].reset(g, static_cast<units_t>(f.initial));
      else
        reals[id].reset(g, f.initial);
    });
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
