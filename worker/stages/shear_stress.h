// SPDX-License-Identifier: Apache-2.0
// The shear stress of the wind over relief, physical modes only
// (docs/physical-units.md, "The shear stress over relief").
//
// The linear theory of a turbulent boundary layer over a low hill (Jackson &
// Hunt 1975), in the form of Kroy, Sauermann & Herrmann 2002 (their eq. for
// the Fourier transform of the stress perturbation, k_x along the wind):
//   tau1_hat / tau0 = A (k_x^2 / |k| + i B k_x) h_hat.
// In real space, with e the wind's unit vector and D h = e . grad h, k_x^2 /
// |k| is the convolution of D h with K(r) = (e . r) / (2 pi |r|^3) (the
// gradient of the kernel 1 / (2 pi |r|) of 1 / |k|; integrated across the
// wind it is the Hilbert kernel 1 / (pi x) of the two-dimensional theory)
// and i k_x is D h itself:
//   tau1 / tau0 = A [ (K * D h) + B D h ].
// The stress rises over the windward slope, peaks upwind of the crest (the B
// term) and falls in the lee; u* follows sqrt(tau):
//   u* = u*0 sqrt(max(1 + tau1 / tau0, 0)).
//
// It is computed on the coarse window of the wind warping
// (stages/wind_warping.h): the exact coarse block means of the heights,
// central differences, the kernel truncated at a radius that the coarse
// halo covers, every sum in one fixed order; then interpolated to the fine
// cells with the warping's bilinear weights. Every coarse output is then a
// function of the same coarse values in the same order on any tiling, so the
// bits do not depend on it (docs/design.md, "Wind warping").
#pragma once

#include <cmath>
#include <vector>

#include "core/hd.h"
#include "core/vec2.h"
#include "stages/wind_warping.h"

namespace erg::shear_stress {

struct Params {
  bool on = false;     // physical modes with A > 0
  float a = 0, b = 0;  // A, B of Kroy et al. 2002
  int radius = 0;      // kernel taps on each side, in coarse cells
};

// The kernel radius in coarse cells of a reach in metres (host).
inline int kernel_radius(double radius_m, double delta_m) {
  return static_cast<int>(std::ceil(radius_m / delta_m - 1e-9));
}

// The truncated kernel (host), for the wind direction (ex, ey) (a unit
// vector): the taps of one half plane, the other half being their negatives
// (K is odd): for offsets (u, v) in coarse cells with v > 0, or v == 0 and
// u > 0, within the radius, in row-major order of v then u,
// k[n] = (ex u + ey v) / (2 pi (u^2 + v^2)^(3/2)), i.e. K(r) times the
// coarse cell's area delta^2 (the operator has no length scale: delta
// cancels). Returns the number of taps; `k`, `du`, `dv` hold
// kernel_capacity(r) entries.
inline int kernel(double ex, double ey, int r, double* k, int* du, int* dv) {
  constexpr double kTwoPi = 6.283185307179586;
  int n = 0;
  for (int v = 0; v <= r; ++v)
    for (int u = -r; u <= r; ++u) {
      if (v == 0 && u <= 0) continue;
      const double d2 = static_cast<double>(u) * u + static_cast<double>(v) * v;
      if (d2 > static_cast<double>(r) * r) continue;  // a disc: the same reach in every direction
      k[n] = (ex * u + ey * v) / (kTwoPi * d2 * std::sqrt(d2));
      du[n] = u;
      dv[n] = v;
      ++n;
    }
  return n;
}
inline int kernel_capacity(int r) {
  return (2 * r + 1) * (2 * r + 1) / 2 + 1;
}

// The taps for the direction of the step's high-altitude wind a (host): the
// perturbation is taken along the undisturbed wind (k_x of Kroy et al.),
// one direction for the whole domain, so the taps are built once per
// direction. aim returns false when a is still air (no perturbation).
struct Kernel {
  std::vector<double> k;
  std::vector<int> du, dv;
  int taps = 0;
  double ex = 0, ey = 0;
  bool aim(Vec2 a, int r) {
    const double ax = a.x, ay = a.y, len = std::sqrt(ax * ax + ay * ay);
    if (!(len > 0.0)) return false;
    const double x = ax / len, y = ay / len;
    if (taps > 0 && x == ex && y == ey) return true;
    ex = x;
    ey = y;
    k.resize(static_cast<size_t>(kernel_capacity(r)));
    du.resize(k.size());
    dv.resize(k.size());
    taps = kernel(ex, ey, r, k.data(), du.data(), dv.data());
    return true;
  }
};

// D h = e . grad h by central differences at window cell (i, j) of a
// window `wx` wide (metres per metre).
ERG_HD double slope_at(const double* window, int wx, double ex, double ey, double delta_m, int i,
                       int j) {
  const double* c = window + static_cast<long>(j) * wx + i;
  const double gx = (c[1] - c[-1]) / (2.0 * delta_m);
  const double gy = (c[wx] - c[-wx]) / (2.0 * delta_m);
  return ex * gx + ey * gy;
}

// tau1 / tau0 at window cell (i, j): A [ sum_n k[n] (D(p - o_n) - D(p + o_n))
// + B D(p) ], `slope` holding D h over the window (`wx` wide), the taps
// summed in the kernel's order.
ERG_HD float perturbation_at(const double* slope, int wx, const double* k, const int* du,
                             const int* dv, int taps, Params p, int i, int j) {
  const double* c = slope + static_cast<long>(j) * wx + i;
  double s = 0.0;
  for (int n = 0; n < taps; ++n) {
    const long o = static_cast<long>(dv[n]) * wx + du[n];
    s += k[n] * (c[-o] - c[o]);
  }
  return static_cast<float>(static_cast<double>(p.a) * (s + static_cast<double>(p.b) * c[0]));
}

// The speed-up of u* (and of the surface wind, which carries it) for a
// stress perturbation: sqrt(max(1 + tau1 / tau0, 0)); 1 on flat ground,
// exactly.
ERG_HD float speedup(float tau1) {
  return sqrtf(max_of(1.0f + tau1, 0.0f));
}

}  // namespace erg::shear_stress
