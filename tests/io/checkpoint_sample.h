// SPDX-License-Identifier: Apache-2.0
// The checkpoint both checkpoint tests write and read back (serial HDF5 in
// test_checkpoint.cpp, collective parallel HDF5 in test_io_parallel.cpp): the
// extremes of int64 units and of float bit patterns, the same on every rank
// (fixed seed).
#pragma once

#include <cstdint>
#include <iterator>
#include <limits>
#include <random>
#include <string>

#include "core/fields.h"
#include "io/io.h"

namespace erg::io::testing {

inline constexpr std::int64_t kP62 = std::int64_t{1} << 62;

inline Checkpoint sample_checkpoint(int nx, int ny) {
  Checkpoint c;
  c.step = 987654321012;
  c.nx = nx;
  c.ny = ny;
  c.job_spec_json = "{\"grid\": {\"nx\": " + std::to_string(nx) + "}}";
  const std::size_t n = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  std::mt19937_64 rng(7);
  const std::int64_t edge[] = {kP62,
                               -kP62,
                               kP62 - 1,
                               -kP62 + 1,
                               kP62 + 12345,
                               -kP62 - 12345,
                               std::numeric_limits<std::int64_t>::max(),
                               std::numeric_limits<std::int64_t>::min(),
                               0,
                               -1,
                               1};
  for (std::size_t i = 0; i < n; ++i) {
    // Near +-2^62, low bits random: the bits that float conversion would lose.
    const std::int64_t noise = static_cast<std::int64_t>(rng() % 1000003);
    c.units[erg::fields::kBedrock].push_back(i < std::size(edge) ? edge[i] : kP62 - noise);
    c.units[erg::fields::kSand].push_back(i % 2 ? -kP62 + noise
                                                : static_cast<std::int64_t>(rng() >> 2));
    c.units[erg::fields::kAirborne].push_back(static_cast<std::int64_t>(rng()));
    c.reals[erg::fields::kVegetation].push_back(static_cast<float>(i % 101) / 100.0f);
    c.reals[erg::fields::kResistance].push_back(i == 0   ? -0.0f
                                                : i == 1 ? 1e-40f
                                                         : static_cast<float>(rng() % 997) * 1e-3f);
  }
  // Deliberately not in name order: the order must survive.
  c.ledger = {{"sand_added", "170141183460469231731687303715884105727"},
              {"bedrock_eroded", "-170141183460469231731687303715884105728"},
              {"airborne_lost", "0"}};
  return c;
}

}  // namespace erg::io::testing
