// SPDX-License-Identifier: Apache-2.0
// Counter-based random numbers: Philox4x32-10 (Salmon et al., SC 2011).
// A draw depends only on (seed, step, global cell index, event), never on the
// order cells are visited, so stochastic transport gives the same result on
// every thread count, tiling, rank count and backend (docs/design.md,
// "Exactness").
#pragma once

#include <cstdint>

#include "core/hd.h"

namespace erg {

struct Philox4 {
  std::uint32_t v[4];
};

ERG_HD void philox_mulhilo(std::uint32_t a, std::uint32_t b, std::uint32_t& hi, std::uint32_t& lo) {
  const std::uint64_t p = static_cast<std::uint64_t>(a) * b;
  hi = static_cast<std::uint32_t>(p >> 32);
  lo = static_cast<std::uint32_t>(p);
}

// counter: 4 words; key: 2 words.
ERG_HD Philox4 philox4x32_10(Philox4 ctr, std::uint32_t k0, std::uint32_t k1) {
  constexpr std::uint32_t M0 = 0xD2511F53u, M1 = 0xCD9E8D57u;
  constexpr std::uint32_t W0 = 0x9E3779B9u, W1 = 0xBB67AE85u;
  for (int round = 0; round < 10; ++round) {
    std::uint32_t hi0, lo0, hi1, lo1;
    philox_mulhilo(M0, ctr.v[0], hi0, lo0);
    philox_mulhilo(M1, ctr.v[2], hi1, lo1);
    Philox4 next;
    next.v[0] = hi1 ^ ctr.v[1] ^ k0;
    next.v[1] = lo1;
    next.v[2] = hi0 ^ ctr.v[3] ^ k1;
    next.v[3] = lo0;
    ctr = next;
    k0 += W0;
    k1 += W1;
  }
  return ctr;
}

// What a draw is for; part of the counter so that draws never collide.
enum class RandomStream : std::uint32_t {
  kLift = 1,
  kLanding = 2,
  kDeposit = 3,
  kWindRose = 4,
  kWindRoseJitter = 5,
  kGenerator = 6,
  kPatches = 7,
};

// Uniform float in [0, 1) with 24 random bits.
ERG_HD float u01(std::uint32_t x) {
  return static_cast<float>(x >> 8) * (1.0f / 16777216.0f);
}
// Uniform double in [0, 1) with 53 random bits.
ERG_HD double u01d(std::uint32_t hi, std::uint32_t lo) {
  const std::uint64_t b = (static_cast<std::uint64_t>(hi) << 21) ^ (lo >> 11);
  return static_cast<double>(b & ((1ull << 53) - 1)) * (1.0 / 9007199254740992.0);
}

// Four random words for (seed, step, cell, stream).
ERG_HD Philox4 random4(std::uint64_t seed, std::uint64_t step, std::uint64_t cell,
                       RandomStream stream) {
  Philox4 c;
  c.v[0] = static_cast<std::uint32_t>(cell);
  c.v[1] = static_cast<std::uint32_t>(cell >> 32);
  c.v[2] = static_cast<std::uint32_t>(step);
  c.v[3] = static_cast<std::uint32_t>(step >> 32) ^ (static_cast<std::uint32_t>(stream) << 24);
  return philox4x32_10(c, static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32));
}

}  // namespace erg
