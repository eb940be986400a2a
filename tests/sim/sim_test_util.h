// SPDX-License-Identifier: Apache-2.0
// Helpers for simulation tests: jobs from JSON text, runs, field access.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "job/spec.h"
#include "sim/simulation.h"

namespace erg::test {

// A defaults-filled, validated spec from JSON text; fails the test if invalid.
inline erg::v1::JobSpec spec_from(const std::string& json) {
  erg::v1::JobSpec spec = job::parse_json(json, "test job");
  job::apply_defaults(spec);
  const auto problems = job::validate(spec);
  for (const auto& p : problems) ADD_FAILURE() << p;
  return spec;
}

inline RunOptions cpu_threads(int threads) {
  RunOptions o;
  o.backend = BackendKind::kCpu;
  o.threads = threads;
  return o;
}

// Owned cells of a field, row-major [ny][nx].
template <class T>
std::vector<T> owned(const Field<T>& f) {
  return owned_cells(f);
}

// Height (bedrock + sand) in metres, owned cells.
inline std::vector<double> heights_m(const TileState& s) {
  const TileGeom& g = s.geom;
  std::vector<double> h(static_cast<size_t>(g.nx) * g.ny);
  for (int y = 0; y < g.ny; ++y)
    for (int x = 0; x < g.nx; ++x)
      h[static_cast<size_t>(y) * g.nx + x] =
          units_to_m_d(s.units[erg::fields::kBedrock](x, y) + s.units[erg::fields::kSand](x, y));
  return h;
}

inline std::vector<double> sand_m(const TileState& s) {
  const TileGeom& g = s.geom;
  std::vector<double> h(static_cast<size_t>(g.nx) * g.ny);
  for (int y = 0; y < g.ny; ++y)
    for (int x = 0; x < g.nx; ++x)
      h[static_cast<size_t>(y) * g.nx + x] = units_to_m_d(s.units[erg::fields::kSand](x, y));
  return h;
}

}  // namespace erg::test
