// SPDX-License-Identifier: Apache-2.0
// Local wind primitives ([P19] 4.4): a user-placed, time-varying
// perturbation u(p, t) added to the warped surface wind, before the shadow.
// As in Bridson et al. 2007, "Curl-noise for procedural fluid flow" [BHN07],
// u is the curl of a scalar stream function psi,
//   u = curl(psi e_z) = (d psi / dy, -d psi / dx),
// which is divergence-free whatever psi is. A vortex is a radial bump of psi
// (counter-clockwise for psi > 0); turbulence is tileable gradient noise
// times a smooth disk mask ([BHN07] section 3: modulating psi, not u, keeps
// the field divergence-free).
//
// Discrete operator. psi is sampled at cell corners (i l, j l); the wind of
// cell (i, j), centred at ((i + 1/2) l, (j + 1/2) l), is the difference of the
// corner values across the cell, averaged over its two edges:
//   u_x =  [(psi(i, j+1) + psi(i+1, j+1)) - (psi(i, j) + psi(i+1, j))] / 2l
//   u_y = -[(psi(i+1, j) + psi(i+1, j+1)) - (psi(i, j) + psi(i, j+1))] / 2l
// that is u_x = A_x D_y psi and u_y = -A_y D_x psi, with A an average and D a
// difference of two neighbours. The matching divergence lives at corners and
// reads the four cells around one (divergence_at_corner below):
//   div = A_y D_x u_x + A_x D_y u_y = (A_y D_x A_x D_y - A_x D_y A_y D_x) psi = 0
// because these shift operators commute: the discrete field has no sources
// up to the rounding of its values, whatever psi is, so the taper of a vortex
// or the mask of a turbulence region never creates any.
//
// psi depends only on the primitive and the global corner index (wrapped on
// the torus, so the seam is seamless bit for bit): every tile, thread count
// and restart computes the same bits, and no halo is read. The math runs in
// double; the sum of a batch of primitives is added to the float wind once.
#pragma once

#include <cstdint>

#include "core/hash.h"
#include "core/hd.h"
#include "core/vec2.h"

namespace erg::wind_primitives {

enum Kind : int { kVortex = 0, kTurbulence = 1 };

// Vortex taper: psi is cut smoothly to 0 between kTaperStart R and kSupport R
// (for p = 2 the speed there is below 0.2 % of the peak).
inline constexpr double kTaperStart = 4.0, kSupport = 5.0;
// RMS of |grad n| (lattice units) of gradient_noise: psi = a lambda / kNoiseRmsGradient * n
// gives an rms speed a (measured over 2^20 samples of 4 seeds; tests check it).
inline constexpr double kNoiseRmsGradient = 0.8813;

// One primitive at one step, resolved on the host (wind/primitives.cpp) with
// its time envelope folded into `amp`. Plain data: passed to kernels by value.
struct Primitive {
  int kind = kVortex;
  int gnx = 1, gny = 1;       // domain in cells (corner indices wrap)
  double cell_m = 1;          // l
  double lx_m = 1, ly_m = 1;  // domain extent
  double cx_m = 0, cy_m = 0;  // vortex centre; turbulence region centre; in [0, L)
  double amp = 0;             // psi scale (m^2/s), envelope included
  // vortex
  double radius_m = 1, exponent = 2;
  // turbulence
  double region_m = -1;                 // region radius; < 0: the whole domain
  double falloff_m = 1;                 // smooth edge inside region_m
  double shift_x_m = 0, shift_y_m = 0;  // drift of the pattern, in [0, L)
  double w1 = 1, w2 = 0;                // blend of the two noise fields (cos, sin)
  int px = 1, py = 1;                   // noise lattice cells along x and y
  std::uint32_t seed1 = 0, seed2 = 0;
  // The cells psi can reach, a box on the torus: cells bx0 .. bx0 + bw - 1
  // (wrapping; bx0 in [0, gnx), bw = gnx: every column), the same for y.
  // Outside it a primitive leaves the wind untouched.
  int bx0 = 0, bw = 1, by0 = 0, bh = 1;
};

// Primitives are applied in batches of this many per pass (one kernel launch
// on the GPU, arguments by value).
inline constexpr int kBatch = 8;
struct Batch {
  Primitive p[kBatch];
  int n = 0;
};

// d = x - c with x and c in [0, period): into [-period/2, period/2).
ERG_HD double wrap_delta(double d, double period) {
  if (d >= 0.5 * period) d -= period;
  if (d < -0.5 * period) d += period;
  return d;
}

// Whether global cell g is in the span b0 .. b0 + w - 1 of an axis of n
// cells (g and b0 in [0, n)).
ERG_HD bool in_span(int g, int b0, int w, int n) {
  int d = g - b0;
  if (d < 0) d += n;
  return d < w;
}
ERG_HD bool covers(const Primitive& P, int gx, int gy) {
  return in_span(gx, P.bx0, P.bw, P.gnx) && in_span(gy, P.by0, P.bh, P.gny);
}

ERG_HD double smoothstep01(double t) {
  t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
  return t * t * (3.0 - 2.0 * t);
}

// exp(-s^p / p), tapered to 0 over [kTaperStart, kSupport]; its slope peaks
// at s = 1 with value -e^(-1/p).
ERG_HD double vortex_profile(double s, double p) {
  if (s >= kSupport) return 0.0;
  const double g = p == 2.0 ? exp(-0.5 * (s * s)) : exp(-pow(s, p) / p);
  return s <= kTaperStart ? g : g * smoothstep01(kSupport - s);
}

// The sum over the periodic images of the vortex (radius <= 0.3 of the
// domain, validated, so the images beyond the nearest ones are outside
// the support).
ERG_HD double vortex_psi(const Primitive& P, double x, double y) {
  const double dx0 = wrap_delta(x - P.cx_m, P.lx_m), dy0 = wrap_delta(y - P.cy_m, P.ly_m);
  const double support = kSupport * P.radius_m;
  double psi = 0.0;
  for (int iy = -1; iy <= 1; ++iy) {
    const double dy = dy0 + iy * P.ly_m;
    if (dy >= support || dy <= -support) continue;
    for (int ix = -1; ix <= 1; ++ix) {
      const double dx = dx0 + ix * P.lx_m;
      if (dx >= support || dx <= -support) continue;
      const double r2 = dx * dx + dy * dy;
      if (r2 >= support * support) continue;
      psi += vortex_profile(sqrt(r2) / P.radius_m, P.exponent);
    }
  }
  return P.amp * psi;
}

using erg::hash3;  // core/hash.h

// Gradient (dot) of the lattice point (i, j), period (px, py), with one of 8
// unit gradients picked by the hash (no trigonometry per point).
ERG_HD double lattice_dot(long long i, long long j, int px, int py, std::uint32_t seed, double du,
                          double dv) {
  // i in [-px, 2px] and j in [-py, 2py] (corners and shift inside the domain).
  i = i < 0 ? i + px : (i >= px ? i - px : i);
  j = j < 0 ? j + py : (j >= py ? j - py : j);
  const std::uint32_t gi = static_cast<std::uint32_t>(i), gj = static_cast<std::uint32_t>(j);
  const std::uint32_t h = hash3(gi, gj, seed) & 7u;
  const double s = 0.7071067811865476;
  const double gx = h == 0 ? 1.0 : h == 1 ? -1.0 : h < 4 ? 0.0 : ((h & 1u) ? -s : s);
  const double gy = h < 2 ? 0.0 : h == 2 ? 1.0 : h == 3 ? -1.0 : ((h & 2u) ? -s : s);
  return gx * du + gy * dv;
}

// Periodic gradient noise (quintic fade, C2) at lattice coordinates (u, v).
ERG_HD double gradient_noise(double u, double v, int px, int py, std::uint32_t seed) {
  const double fu = floor(u), fv = floor(v);
  const double tu = u - fu, tv = v - fv;
  const long long iu = static_cast<long long>(fu), iv = static_cast<long long>(fv);
  const double n00 = lattice_dot(iu, iv, px, py, seed, tu, tv);
  const double n10 = lattice_dot(iu + 1, iv, px, py, seed, tu - 1.0, tv);
  const double n01 = lattice_dot(iu, iv + 1, px, py, seed, tu, tv - 1.0);
  const double n11 = lattice_dot(iu + 1, iv + 1, px, py, seed, tu - 1.0, tv - 1.0);
  const double a = tu * tu * tu * (tu * (tu * 6.0 - 15.0) + 10.0);
  const double b = tv * tv * tv * (tv * (tv * 6.0 - 15.0) + 10.0);
  const double nx0 = n00 + a * (n10 - n00), nx1 = n01 + a * (n11 - n01);
  return nx0 + b * (nx1 - nx0);
}

// The region mask: 1 inside region_m - falloff_m, smoothstep to 0 at region_m.
ERG_HD double region_mask(const Primitive& P, double x, double y) {
  if (P.region_m < 0.0) return 1.0;
  const double dx = wrap_delta(x - P.cx_m, P.lx_m), dy = wrap_delta(y - P.cy_m, P.ly_m);
  const double d = sqrt(dx * dx + dy * dy);
  return smoothstep01((P.region_m - d) / P.falloff_m);
}

ERG_HD double turbulence_psi(const Primitive& P, double x, double y) {
  const double mask = region_mask(P, x, y);
  if (mask == 0.0) return 0.0;
  const double u = (x - P.shift_x_m) * P.px / P.lx_m, v = (y - P.shift_y_m) * P.py / P.ly_m;
  double n = P.w1 * gradient_noise(u, v, P.px, P.py, P.seed1);
  if (P.w2 != 0.0) n += P.w2 * gradient_noise(u, v, P.px, P.py, P.seed2);
  return P.amp * mask * n;
}

// psi at global corner (ci, cj), wrapped onto the torus.
ERG_HD double psi_at_corner(const Primitive& P, int ci, int cj) {
  ci = ci < 0 ? ci + P.gnx : (ci >= P.gnx ? ci - P.gnx : ci);  // ci in [-gnx, 2 gnx)
  cj = cj < 0 ? cj + P.gny : (cj >= P.gny ? cj - P.gny : cj);
  const double x = ci * P.cell_m, y = cj * P.cell_m;
  return P.kind == kVortex ? vortex_psi(P, x, y) : turbulence_psi(P, x, y);
}

struct Velocity {
  double x, y;
};

// The discrete curl of one cell from psi at its corners (operator above).
ERG_HD Velocity curl_of_corners(double p00, double p10, double p01, double p11, double cell_m) {
  const double inv = 0.5 / cell_m;
  return {((p01 + p11) - (p00 + p10)) * inv, -((p10 + p11) - (p00 + p01)) * inv};
}
ERG_HD Velocity velocity_at(const Primitive& P, int gx, int gy) {
  return curl_of_corners(psi_at_corner(P, gx, gy), psi_at_corner(P, gx + 1, gy),
                         psi_at_corner(P, gx, gy + 1), psi_at_corner(P, gx + 1, gy + 1), P.cell_m);
}

// The matching divergence at global corner (ci, cj), from the velocities of
// its four cells: u(i, j) of cell (ci + i - 1, cj + j - 1), i, j in {0, 1}.
ERG_HD double divergence_at_corner(Velocity u00, Velocity u10, Velocity u01, Velocity u11,
                                   double cell_m) {
  const double inv = 0.5 / cell_m;
  return ((u10.x + u11.x) - (u00.x + u01.x)) * inv + ((u01.y + u11.y) - (u00.y + u10.y)) * inv;
}

// The wind of global cell (gx, gy) plus the perturbation of the batch's
// primitives whose box covers it, summed in batch order in double and added
// once; untouched when none does (so a backend may skip those cells).
ERG_HD Vec2 add_batch(Vec2 w, const Batch& b, int gx, int gy) {
  double ux = 0.0, uy = 0.0;
  bool any = false;
  for (int k = 0; k < b.n; ++k) {
    if (!covers(b.p[k], gx, gy)) continue;
    const Velocity u = velocity_at(b.p[k], gx, gy);
    ux += u.x;
    uy += u.y;
    any = true;
  }
  if (!any) return w;
  return {w.x + static_cast<float>(ux), w.y + static_cast<float>(uy)};
}

}  // namespace erg::wind_primitives
