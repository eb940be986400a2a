// SPDX-License-Identifier: Apache-2.0
// Exact height units. Sand, bedrock and airborne sand are held as int64
// counts of 2^-32 m (about 0.23 nm). Every transfer subtracts from the donor
// exactly what it adds to the receiver, and integer sums do not depend on
// order, so the total mass is conserved to the last unit on any thread count,
// tiling or backend (docs/design.md, "Exactness"). Geometry and wind use float
// metres derived from these integers; outputs are float32 metres.
//
// Range: +-2^63 units = +-2.1e9 m, far beyond any terrain. Domain totals use
// 128-bit sums (a 1e5 x 1e5 domain of 100 m sand is 4e21 units).
#pragma once

#include <cstdint>
#include <string>

#include "core/hd.h"

namespace erg {

using units_t = std::int64_t;
using total_t = __int128;

inline constexpr int kUnitBits = 32;
inline constexpr double kUnitM = 1.0 / 4294967296.0;  // metres per unit (2^-32)
inline constexpr double kUnitsPerM = 4294967296.0;    // 2^32
inline constexpr float kUnitMf = 1.0f / 4294967296.0f;
inline constexpr float kUnitsPerMf = 4294967296.0f;

// Float metres of an integer height. Scaling by a power of two is exact, so
// this is the correctly rounded value of u * 2^-32 everywhere.
ERG_HD float units_to_m(units_t u) {
  return static_cast<float>(u) * kUnitMf;
}
ERG_HD double units_to_m_d(units_t u) {
  return static_cast<double>(u) * kUnitM;
}

// Whole units in an amount x >= 0 (in units, finite, < 2^62): floor(x).
// Every transfer is a non-negative amount, and for x >= 0 floor is the
// truncating conversion, which vectorises (floorf does not without
// -fno-trapping-math); negative amounts count as nothing.
ERG_HD units_t floor_units(float x) {
  return static_cast<units_t>(max_of(x, 0.0f));
}
ERG_HD units_t floor_units_d(double x) {
  return static_cast<units_t>(max_of(x, 0.0));
}

// Nearest integer count of a length in metres (initial maps, brushes).
inline units_t m_to_units(double m) {
  return static_cast<units_t>(std::llround(m * kUnitsPerM));
}

// Exact decimal text of a 128-bit total (snapshot attributes, logs).
inline std::string to_decimal(total_t v) {
  if (v == 0) return "0";
  bool neg = v < 0;
  unsigned __int128 u =
      neg ? static_cast<unsigned __int128>(-(v + 1)) + 1 : static_cast<unsigned __int128>(v);
  std::string s;
  while (u > 0) {
    s.insert(s.begin(), static_cast<char>('0' + static_cast<int>(u % 10)));
    u /= 10;
  }
  return neg ? "-" + s : s;
}

inline total_t parse_decimal(const std::string& s) {
  bool neg = !s.empty() && s[0] == '-';
  total_t v = 0;
  for (size_t i = neg ? 1 : 0; i < s.size(); ++i) v = v * 10 + (s[i] - '0');
  return neg ? -v : v;
}

}  // namespace erg
