// SPDX-License-Identifier: Apache-2.0
// Tileable gradient noise: Perlin-style noise on a lattice of period (px, py),
// so the field wraps seamlessly on the torus. Evaluated per cell from a hash
// of the lattice point: any tile of the domain computes the same values.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/hash.h"

namespace erg::init {

using erg::hash3;  // core/hash.h

// Noise in about [-1, 1] at lattice coordinates (u, v), periods px, py >= 1.
inline double periodic_gradient_noise(double u, double v, int px, int py, std::uint32_t seed) {
  const double fu = std::floor(u), fv = std::floor(v);
  const double tu = u - fu, tv = v - fv;
  const long iu = static_cast<long>(fu), iv = static_cast<long>(fv);
  auto grad_dot = [&](long i, long j, double du, double dv) {
    const std::uint32_t gi = static_cast<std::uint32_t>(((i % px) + px) % px);
    const std::uint32_t gj = static_cast<std::uint32_t>(((j % py) + py) % py);
    const double a = (hash3(gi, gj, seed) & 0xFFFFFF) * (6.283185307179586 / 16777216.0);
    return std::cos(a) * du + std::sin(a) * dv;
  };
  auto fade = [](double t) { return t * t * t * (t * (t * 6 - 15) + 10); };
  const double n00 = grad_dot(iu, iv, tu, tv), n10 = grad_dot(iu + 1, iv, tu - 1, tv);
  const double n01 = grad_dot(iu, iv + 1, tu, tv - 1),
               n11 = grad_dot(iu + 1, iv + 1, tu - 1, tv - 1);
  const double a = fade(tu), b = fade(tv);
  const double nx0 = n00 + a * (n10 - n00), nx1 = n01 + a * (n11 - n01);
  // Gradient noise with unit gradients peaks near +-0.71: scale to about +-1.
  return 1.4142135623730951 * (nx0 + b * (nx1 - nx0));
}

}  // namespace erg::init
