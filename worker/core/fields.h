// SPDX-License-Identifier: Apache-2.0
// The field registry: every per-cell field of a tile, declared once (the
// Parthenon way: a field and its metadata, from which storage, outputs and
// ghost exchanges follow).
//
// A field's entry says what it holds (integer height units or float), its
// unit, whether it is exact state (checkpointed; everything else is derived
// from the state each step), whether and how it appears in snapshots, which
// stages read its ghosts (the exchange width follows from their reach, see
// Reach and sim/model.h), and its default. The backends allocate one padded
// buffer per entry (ByField); snapshots, checkpoints, the parallel HDF5
// writers and readers and the XDMF sidecars loop over the entries.
//
// Adding a field (README, "Adding a field"): one entry here, and the stage
// that fills it. Keep `Id` and kFields in the same order.
#pragma once

#include <array>
#include <cstddef>
#include <string_view>

#include "core/units.h"

namespace erg::fields {

enum class Type { kUnits, kFloat };  // int64 units of kUnitM metres (core/units.h), or float

// The ghost cells a field must have filled before the stages that read them
// (sim/model.h, Model::halo_width gives the width in cells).
enum class Reach {
  kNone,       // no stage reads its ghosts
  kShadow,     // the shadow march and the echo-dune search (heights upwind)
  kSaltation,  // hop reach + bilinear footprint (the scatter target, summed back)
  kReptation,  // reptation plus the first avalanching round, which run on the grown tile
  kAvalanche,  // the widest avalanching round plus one (per-cell constants of avalanching)
  kWhole,      // the whole halo (obstacle walls: hop paths, echo dunes, avalanching)
};

// How a field appears in snapshots (float32 [1][ny][nx], CF metadata, an XDMF
// attribute). position 0: not in snapshots.
struct Snapshot {
  int position = 0;  // order of the layers in a snapshot file (1 first)
  const char* long_name = "";
  const char* standard_name = "";  // from the CF standard name table; "" where none fits
  bool optional = false;           // older snapshots may lack it (readers leave it empty)
};

// Whether a field has storage of its own on the CPU backend, or shares it
// with others whose lifetimes within a step do not overlap (docs/design.md,
// "Memory"; backend/cpu/cpu_backend.h says who shares what). Conserved
// quantities are always integer units, shared or not.
enum class Storage {
  kOwn,         // its own buffer
  kRecomputed,  // shares a work buffer; computed again when read after its
                // storage was reused (wind, shadow: from the step's heights
                // and wind; repose tangents: from vegetation)
  kReplaced,    // the stage that reads it last writes another field over it,
                // cell by cell (landed -> deposited_m, reptation -> tan_l);
                // its values live from the stage that writes it to that one
};

struct Info {
  const char* name;  // the snapshot dataset, and the field's name everywhere
  Type type;
  const char* unit;  // UDUNITS of the physical value ("m", "1", "m s-1"); kUnits: metres
  // Exact state: written to and read from checkpoints (dataset `checkpoint`).
  bool state;
  const char* checkpoint;    // "" when not state
  bool checkpoint_optional;  // older checkpoints lack it: the default is used
  Snapshot snapshot;
  Reach ghosts;   // who reads its ghosts
  float initial;  // the value before anything sets it (and of a missing optional dataset)
  Storage storage = Storage::kOwn;  // on the CPU backend
  const char* shares = "";          // what it shares storage with (kOwn: nothing)
};

enum Id : int {
  // Exact state, in checkpoint order.
  kBedrock,
  kSand,
  kAirborne,
  kVegetation,
  kResistance,
  kObstacles,
  // Derived each step.
  kHeight,
  kWindX,
  kWindY,
  kShadow,
  kEcho,
  kLanded,
  kReptation,
  kTanL,
  kDeposited,
  kCount
};

inline constexpr std::array<Info, kCount> kFields = {{
    {"bedrock",
     Type::kUnits,
     "m",
     true,
     "bedrock_units",
     false,
     {1, "bedrock surface height above the model datum"},
     Reach::kReptation,
     0},
    {"sand",
     Type::kUnits,
     "m",
     true,
     "sand_units",
     false,
     {2, "thickness of the sand on the ground"},
     Reach::kReptation,
     0},
    {"airborne",
     Type::kUnits,
     "m",
     true,
     "airborne_units",
     false,
     {6, "thickness of the sand in saltation (as deposited)", "", true},
     Reach::kNone,
     0},
    {"vegetation",
     Type::kFloat,
     "1",
     true,
     "vegetation",
     false,
     {3, "vegetation cover fraction", "vegetation_area_fraction"},
     Reach::kAvalanche,  // the CPU backend derives tan_l from it, ghosts included
     0},
    {"resistance", Type::kFloat, "1", true, "resistance", false, {}, Reach::kNone, 0},
    {"obstacles",
     Type::kFloat,
     "m",
     true,
     "obstacles",
     true,
     {8, "obstacle height above the ground (0: none)", "", true},
     Reach::kWhole,
     0},
    // b + s + o in metres: what the wind sees.
    {"height", Type::kFloat, "m", false, "", false, {}, Reach::kShadow, 0},
    {"wind_x",
     Type::kFloat,
     "m s-1",
     false,
     "",
     false,
     {4, "surface wind, x (eastward) component", "eastward_wind"},
     Reach::kNone,
     0,
     Storage::kRecomputed,
     "reptation's new sand, avalanching's heights"},
    {"wind_y",
     Type::kFloat,
     "m s-1",
     false,
     "",
     false,
     {5, "surface wind, y (northward) component", "northward_wind"},
     Reach::kNone,
     0,
     Storage::kRecomputed,
     "reptation's new sand, avalanching's fractions"},
    {"shadow",
     Type::kFloat,
     "1",
     false,
     "",
     false,
     {7, "wind shadow of the upwind relief", "", true},
     Reach::kNone,
     0,
     Storage::kRecomputed,
     "reptation, tan_l"},
    // Echo-dune classification r_e (stages/echo_dunes.h); 0 when off.
    {"echo", Type::kFloat, "1", false, "", false, {}, Reach::kNone, 0},
    // Saltation's scatter target: airborne sand landing this step, ghosts
    // summed back onto their owners.
    {"landed",
     Type::kUnits,
     "m",
     false,
     "",
     false,
     {},
     Reach::kSaltation,
     0,
     Storage::kReplaced,
     "deposited_m"},
    // s_r, the impact strength that drives reptation [N24 3.6].
    {"reptation",
     Type::kFloat,
     "m",
     false,
     "",
     false,
     {},
     Reach::kReptation,
     0,
     Storage::kReplaced,
     "shadow, tan_l"},
    // tan(repose(v)) * l for sand (stages/vegetation.h).
    {"tan_l",
     Type::kFloat,
     "m",
     false,
     "",
     false,
     {},
     Reach::kAvalanche,
     0,
     Storage::kRecomputed,
     "shadow, reptation"},
    // Sand that saltation deposited on the cell in the last step (landed and
    // stayed; stages/saltation.h Impact::deposited).
    {"deposited_m",
     Type::kUnits,
     "m",
     false,
     "",
     false,
     {9, "sand deposited by saltation in the last step", "", true},
     Reach::kNone,
     0,
     Storage::kOwn,
     "landed (written over it at the impacts)"},
}};

constexpr const Info& info(Id id) {
  return kFields[static_cast<std::size_t>(id)];
}
constexpr bool in_snapshots(Id id) {
  return info(id).snapshot.position > 0;
}
// The snapshot layers, in file order.
inline constexpr int kSnapshotLayers = [] {
  int n = 0;
  for (const Info& f : kFields) n += f.snapshot.position > 0;
  return n;
}();
constexpr std::array<Id, kSnapshotLayers> snapshot_order() {
  std::array<Id, kSnapshotLayers> order{};
  for (int i = 0; i < kCount; ++i)
    if (const int p = kFields[static_cast<std::size_t>(i)].snapshot.position; p > 0)
      order[static_cast<std::size_t>(p - 1)] = static_cast<Id>(i);
  return order;
}
// The state fields, in checkpoint order.
constexpr bool is_state(Id id) {
  return info(id).state;
}
// The field of a snapshot layer or checkpoint dataset name; kCount if none.
constexpr Id by_name(std::string_view name) {
  for (int i = 0; i < kCount; ++i)
    if (name == kFields[static_cast<std::size_t>(i)].name) return static_cast<Id>(i);
  return kCount;
}

// The registry is consistent: snapshot positions are 1..n without gaps or
// repeats, and state fields come first (checkpoint order).
static_assert([] {
  std::array<int, kCount + 1> seen{};
  for (const Info& f : kFields)
    if (f.snapshot.position > 0) {
      if (f.snapshot.position > kSnapshotLayers) return false;
      if (seen[static_cast<std::size_t>(f.snapshot.position)]++) return false;
    }
  bool derived = false;
  for (const Info& f : kFields) {
    if (f.state && derived) return false;
    derived |= !f.state;
    if (f.state != (f.checkpoint[0] != '\0')) return false;
  }
  return true;
}());

// One buffer per registry field: S<units_t> for integer fields, S<float> for
// the others (the unused slot of each pair stays empty). Storage follows the
// registry, so a new entry is allocated, uploaded and saved with the rest.
template <template <class...> class S>
struct ByField {
  std::array<S<units_t>, kCount> units;
  std::array<S<float>, kCount> reals;
};

// A backend's buffers (Field on the host, DeviceBuffer on the GPU), with the
// names the stages call them by: references into the registry's slots.
template <template <class...> class S>
struct Named : ByField<S> {
  Named() = default;
  Named(const Named&) = delete;
  Named& operator=(const Named&) = delete;
  // exact state
  S<units_t>& bedrock = this->units[kBedrock];
  S<units_t>& sand = this->units[kSand];
  S<units_t>& airborne = this->units[kAirborne];
  S<float>& vegetation = this->reals[kVegetation];
  S<float>& resistance = this->reals[kResistance];
  S<float>& obstacles = this->reals[kObstacles];  // ghosts filled over the whole halo
  // derived each step
  S<float>& height_m = this->reals[kHeight];  // halo filled for the shadow march
  S<float>& wind_x = this->reals[kWindX];
  S<float>& wind_y = this->reals[kWindY];
  S<float>& shadow = this->reals[kShadow];
  S<float>& echo = this->reals[kEcho];
  S<units_t>& landed = this->units[kLanded];
  S<float>& reptation = this->reals[kReptation];
  S<float>& tan_l = this->reals[kTanL];
  S<units_t>& deposited = this->units[kDeposited];
};

// Calls f(id, info) for every field of the registry, in registry order.
template <class F>
void each(F&& f) {
  for (int i = 0; i < kCount; ++i) f(static_cast<Id>(i), info(static_cast<Id>(i)));
}

}  // namespace erg::fields
