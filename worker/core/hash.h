// SPDX-License-Identifier: Apache-2.0
// A small integer hash of three words, shared by the host noise generators
// (init/noise.h) and the per-corner curl noise of the wind primitives
// (stages/wind_primitives.h): lattice values that depend only on global
// coordinates and the seed, so every tile and backend computes the same.
#pragma once

#include <cstdint>

#include "core/hd.h"

namespace erg {

// Murmur3-style finaliser over three words.
ERG_HD std::uint32_t hash3(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  std::uint32_t h =
      a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u ^ (c + 0x165667B1u) * 0xC2B2AE3Du;
  h ^= h >> 16;
  h *= 0x85EBCA6Bu;
  h ^= h >> 13;
  h *= 0xC2B2AE35u;
  h ^= h >> 16;
  return h;
}

}  // namespace erg
