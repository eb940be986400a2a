// SPDX-License-Identifier: Apache-2.0
// Bitwise comparison of two snapshot files: every field and the exact totals
// (e2e tests of tiling, restarts and steering), and every level of the
// overview pyramid.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "io/io.h"

namespace erg::test {

inline void expect_same_snapshot(const std::string& a, const std::string& b,
                                 const std::string& what) {
  const auto sa = erg::io::read_snapshot(a);
  const auto sb = erg::io::read_snapshot(b);
  EXPECT_TRUE(sa[erg::fields::kBedrock] == sb[erg::fields::kBedrock]) << what << ": /bedrock";
  EXPECT_TRUE(sa[erg::fields::kSand] == sb[erg::fields::kSand]) << what << ": /sand";
  EXPECT_TRUE(sa[erg::fields::kVegetation] == sb[erg::fields::kVegetation])
      << what << ": /vegetation";
  EXPECT_TRUE(sa.wind == sb.wind) << what << ": /wind";
  EXPECT_TRUE(sa[erg::fields::kAirborne] == sb[erg::fields::kAirborne]) << what << ": /airborne";
  EXPECT_TRUE(sa[erg::fields::kShadow] == sb[erg::fields::kShadow]) << what << ": /shadow";
  EXPECT_TRUE(sa[erg::fields::kObstacles] == sb[erg::fields::kObstacles]) << what << ": /obstacles";
  EXPECT_EQ(sa.meta.sand_units_total, sb.meta.sand_units_total) << what;
  EXPECT_EQ(sa.meta.bedrock_units_total, sb.meta.bedrock_units_total) << what;
  EXPECT_EQ(sa.meta.airborne_units_total, sb.meta.airborne_units_total) << what;
  // The ground range is a reduction over the tiles: the range of the layers.
  for (const auto* s : {&sa, &sb}) {
    const auto& bedrock = (*s)[erg::fields::kBedrock];
    const auto& sand = (*s)[erg::fields::kSand];
    float lo = bedrock[0] + sand[0], hi = lo;
    for (std::size_t c = 0; c < bedrock.size(); ++c) {
      lo = std::min(lo, bedrock[c] + sand[c]);
      hi = std::max(hi, bedrock[c] + sand[c]);
    }
    EXPECT_EQ(s->meta.ground_min_m, static_cast<double>(lo)) << what << ": ground_min_m";
    EXPECT_EQ(s->meta.ground_max_m, static_cast<double>(hi)) << what << ": ground_max_m";
  }
  const int levels = erg::io::overview_levels(sa.meta.nx, sa.meta.ny);
  for (int l = 1; l <= levels; ++l) {
    const auto la = erg::io::read_overview_level(a, l);
    const auto lb = erg::io::read_overview_level(b, l);
    const std::string at = what + ": /overview/level_" + std::to_string(l);
    EXPECT_TRUE(la.bedrock == lb.bedrock) << at << "/bedrock";
    EXPECT_TRUE(la.sand == lb.sand) << at << "/sand";
    EXPECT_TRUE(la.vegetation == lb.vegetation) << at << "/vegetation";
  }
}

}  // namespace erg::test
