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
// term) and falls in the lee. Its component across the wind (the same
// paper, sec. II), k_y along e_perp, the wind's direction turned +90 deg:
//   tau_y_hat / tau0 = A (k_x k_y / |k|) h_hat,
// in real space the same kernel on the slope across the wind, D_perp h =
// e_perp . grad h: tau_y / tau0 = A (K * D_perp h). On the windward flanks
// of a hill it points away from the hill's axis, in the lee towards it: the
// flow goes round the hill. The surface stress is the vector
//   tau / tau0 = (1 + tau1 / tau0) e + (tau_y / tau0) e_perp,
// the along-wind part clipped at 0 (the linear theory's reversed flow, in
// the lee, is not followed; docs/physical-units.md measures the choice);
// u* follows the square root of its magnitude and the
// surface wind turns to its direction (`surface_wind`).
//
// It is computed on the coarse window of the wind warping
// (stages/wind_warping.h): the exact coarse block means of the heights,
// central differences, the kernel truncated at a radius that the coarse
// halo covers, every sum in one fixed order; then interpolated to the fine
// cells with the warping's bilinear weights. That window alone answers a
// dune's faces (wavelengths of 16-32 m on 4 m coarse cells) with 0.23-0.62
// of the theory's K term and 0.47-0.83 of its B term (the block mean, the
// central differences and the interpolation each lose some; measured in
// docs/physical-units.md), so a short correction on the heights, designed
// once from the theory's transfer function divided by the window's own
// (`correction_basis`), brings both within a few percent of the theory
// from 16 m to 128 m: tau1 / tau0 = A [ (K * D h) + B D h + (C * h) ], and
// the same for the component across the wind, tau_y / tau0 = A [ (K *
// D_perp h) + (C_perp * h) ], C_perp designed the same way from the
// theory's k_x k_y / |k|. Every coarse output is then
// a function of the same coarse values in the same order on any tiling, so the bits do not depend
// on it (docs/design.md, "Wind warping").
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
  int cx = 1, cy = 1;  // fine cells per coarse cell along x and y
  double delta_m = 1;  // the coarse cell, metres
};

// A set of taps as the stage reads them: weight w[n] at offset (du[n],
// dv[n]) in coarse cells.
struct TapsView {
  const double* w = nullptr;
  const int* du = nullptr;
  const int* dv = nullptr;
  int n = 0;
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

// The correction C (host, once per model): the taps, over the disc of
// kCorrectionRadius coarse cells without its centre, of the difference
// between the theory's transfer function, A (k_x^2 / |k| + i B k_x) as
// the fine cells should see it, and the window's own (the central
// differences times the truncated kernel, plus B times the central
// differences), divided by A. "As the fine cells should see it": divided by
// the block mean's and the bilinear interpolation's responses, (sin(k / 2)
// / (c sin(k / (2 c))))^3 along each axis for k in radians per coarse cell
// (a block of c fine cells, then the triangle of the interpolation), and
// tapered to 0 between wavelengths of 4 and 2.35 coarse cells (where that
// division would amplify what the coarse grid cannot hold). It is linear
// in the wind's direction e: ex^2 xx + 2 ex ey xy + ey^2 yy + B (ex x + ey
// y), each set the inverse transform, on a kDesignGrid^2 torus of coarse
// cells, of its part of the difference; the sets x and y (odd) lose their
// first moments, so that B D h alone carries the slope at long
// wavelengths. The component across the wind, A k_x k_y / |k| against the
// window's truncated kernel times the central differences across the wind,
// is (ex^2 - ey^2) xy + ex ey (yy - xx) + z with one more set z: the
// window's part that is not of the theory's form (with the truncated
// kernel's transforms Gx, Gy and the central differences' sx, sy, the
// window's lateral response is 2 (ex Gx + ey Gy)(ex sy - ey sx), which
// differs from the theory's in its ex^2 and ey^2 terms by Gy sx - Gx sy).
// Applied as sum_n w[n] (h(p - o_n) - h(p)): exactly 0 on flat ground.
// Plain loops in one fixed order, and cosines from one table, so every rank
// computes the same bits.
constexpr int kCorrectionRadius = 8;  // coarse cells (32 m on 4 m cells)
constexpr int kDesignGrid = 128;      // coarse cells
struct Basis {
  std::vector<double> xx, xy, yy, x, y, z;
  std::vector<int> du, dv;
  int n = 0;
};
inline Basis correction_basis(int radius, int cx, int cy) {
  constexpr double kPi = 3.141592653589793, kTwoPi = 6.283185307179586;
  constexpr int N = kDesignGrid, rc = kCorrectionRadius;
  std::vector<double> cos_t(N), sin_t(N);
  for (int j = 0; j < N; ++j) {
    cos_t[static_cast<size_t>(j)] = std::cos(kTwoPi * j / N);
    sin_t[static_cast<size_t>(j)] = std::sin(kTwoPi * j / N);
  }
  auto idx = [](long j) { return static_cast<size_t>(j & (N - 1)); };  // N: a power of 2
  // The window's truncated kernel (half plane), without the direction.
  std::vector<int> ku, kv;
  std::vector<double> kw;
  for (int v = 0; v <= radius; ++v)
    for (int u = -radius; u <= radius; ++u) {
      if (v == 0 && u <= 0) continue;
      const double d2 = static_cast<double>(u) * u + static_cast<double>(v) * v;
      if (d2 > static_cast<double>(radius) * radius) continue;
      ku.push_back(u);
      kv.push_back(v);
      kw.push_back(1.0 / (kTwoPi * d2 * std::sqrt(d2)));
    }
  auto response = [&](double k, int c) {  // block mean x interpolation, one axis
    if (c <= 1 || k == 0.0) return 1.0;
    const double r = std::sin(0.5 * k) / (c * std::sin(0.5 * k / c));
    return r * r * r;
  };
  auto taper = [&](double k) {  // 1 up to 4 coarse cells, 0 from 2.35
    const double k1 = 0.5 * kPi, k2 = 0.85 * kPi;
    if (k <= k1) return 1.0;
    if (k >= k2) return 0.0;
    return 0.5 * (1.0 + std::cos(kPi * (k - k1) / (k2 - k1)));
  };
  // The six parts of the difference at every wavenumber (m, l) of the torus.
  const size_t nn = static_cast<size_t>(N) * N;
  std::vector<double> cxx(nn), cxy(nn), cyy(nn), cxo(nn), cyo(nn), cz(nn);
  for (int l = 0; l < N; ++l)
    for (int m = 0; m < N; ++m) {
      const int ms = m < N / 2 ? m : m - N, ls = l < N / 2 ? l : l - N;
      const double kx = kTwoPi * ms / N, ky = kTwoPi * ls / N;
      const double kk = std::sqrt(kx * kx + ky * ky);
      const double sx = sin_t[idx(m)], sy = sin_t[idx(l)];
      double gxx = 0, gxy = 0, gyy = 0;
      for (size_t n = 0; n < kw.size(); ++n) {
        const double s = sin_t[idx(static_cast<long>(m) * ku[n] + static_cast<long>(l) * kv[n])];
        gxx += kw[n] * ku[n] * s;
        gxy += kw[n] * (kv[n] * sx + ku[n] * sy) * s;
        gyy += kw[n] * kv[n] * s;
      }
      const double f = kk > 0 ? taper(kk) / (response(kx, cx) * response(ky, cy)) : 0.0;
      const double q = kk > 0 ? f / kk : 0.0;
      const size_t at = static_cast<size_t>(l) * N + m;
      cxx[at] = kx * kx * q - 2.0 * sx * gxx;
      cxy[at] = kx * ky * q - gxy;
      cyy[at] = ky * ky * q - 2.0 * sy * gyy;
      cxo[at] = kx * f - sx;  // times i
      cyo[at] = ky * f - sy;
      cz[at] = gyy * sx - gxx * sy;  // the lateral part's own (even in k)
    }
  Basis b;
  for (int v = -rc; v <= rc; ++v)
    for (int u = -rc; u <= rc; ++u) {
      if ((u == 0 && v == 0) || u * u + v * v > rc * rc) continue;
      double wxx = 0, wxy = 0, wyy = 0, wx = 0, wy = 0, wz = 0;
      for (int l = 0; l < N; ++l)
        for (int m = 0; m < N; ++m) {
          const size_t at = static_cast<size_t>(l) * N + m;
          const size_t ph = idx(static_cast<long>(m) * u + static_cast<long>(l) * v);
          const double c = cos_t[ph], s = sin_t[ph];
          wxx += cxx[at] * c;
          wxy += cxy[at] * c;
          wyy += cyy[at] * c;
          wz += cz[at] * c;
          wx -= cxo[at] * s;  // the real part of i C e^{i k . o}
          wy -= cyo[at] * s;
        }
      const double inv = 1.0 / static_cast<double>(nn);
      b.xx.push_back(wxx * inv);
      b.xy.push_back(wxy * inv);
      b.yy.push_back(wyy * inv);
      b.x.push_back(wx * inv);
      b.y.push_back(wy * inv);
      b.z.push_back(wz * inv);
      b.du.push_back(u);
      b.dv.push_back(v);
    }
  b.n = static_cast<int>(b.du.size());
  // The odd sets without first moments (the disc is symmetric: sum u v = 0,
  // sum u^2 = sum v^2).
  for (std::vector<double>* w : {&b.x, &b.y}) {
    double mu = 0, mv = 0, uu = 0;
    for (int n = 0; n < b.n; ++n) {
      const size_t i = static_cast<size_t>(n);
      mu += (*w)[i] * b.du[i];
      mv += (*w)[i] * b.dv[i];
      uu += static_cast<double>(b.du[i]) * b.du[i];
    }
    for (int n = 0; n < b.n; ++n) {
      const size_t i = static_cast<size_t>(n);
      (*w)[i] -= (mu * b.du[i] + mv * b.dv[i]) / uu;
    }
  }
  return b;
}

// The taps for the direction of the step's high-altitude wind a (host): the
// perturbation is taken along the undisturbed wind (k_x of Kroy et al.),
// one direction for the whole domain, so the taps are built once per
// direction (the correction's basis once per model). aim returns false when
// a is still air (no perturbation).
struct Kernel {
  std::vector<double> k;
  std::vector<int> du, dv;
  int taps = 0;
  double ex = 0, ey = 0;
  Basis basis;
  std::vector<double> c;   // the correction for (ex, ey) and B, over delta_m
  std::vector<double> cp;  // the correction across the wind, over delta_m
  bool aim(Vec2 a, const Params& p) {
    const double ax = a.x, ay = a.y, len = std::sqrt(ax * ax + ay * ay);
    if (!(len > 0.0)) return false;
    const double x = ax / len, y = ay / len;
    if (taps > 0 && x == ex && y == ey) return true;
    ex = x;
    ey = y;
    const int r = p.radius;
    k.resize(static_cast<size_t>(kernel_capacity(r)));
    du.resize(k.size());
    dv.resize(k.size());
    taps = kernel(ex, ey, r, k.data(), du.data(), dv.data());
    if (basis.n == 0) basis = correction_basis(r, p.cx, p.cy);
    c.resize(static_cast<size_t>(basis.n));
    const double b = p.b;
    for (size_t n = 0; n < c.size(); ++n)
      c[n] = (ex * ex * basis.xx[n] + 2.0 * ex * ey * basis.xy[n] + ey * ey * basis.yy[n] +
              b * (ex * basis.x[n] + ey * basis.y[n])) /
             p.delta_m;
    cp.resize(c.size());
    for (size_t n = 0; n < cp.size(); ++n)
      cp[n] =
          ((ex * ex - ey * ey) * basis.xy[n] + ex * ey * (basis.yy[n] - basis.xx[n]) + basis.z[n]) /
          p.delta_m;
    return true;
  }
  TapsView kernel_taps() const { return {k.data(), du.data(), dv.data(), taps}; }
  TapsView correction_taps() const { return {c.data(), basis.du.data(), basis.dv.data(), basis.n}; }
  TapsView lateral_taps() const { return {cp.data(), basis.du.data(), basis.dv.data(), basis.n}; }
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

// The two sums of the stress at window cell (i, j), each in its taps'
// order: s = sum_n k[n] (D(p - o_n) - D(p + o_n)) over `slope` (D), and
// t = sum_n c[n] (h(p - o_n) - h(p)) over `height` (`wx` wide).
struct Sums {
  double s, t, d0;  // d0: D at the cell itself
};
ERG_HD Sums sums_at(const double* slope, const double* height, int wx, TapsView k, TapsView c,
                    int i, int j) {
  const long at = static_cast<long>(j) * wx + i;
  const double* d = slope + at;
  double s = 0.0;
  for (int n = 0; n < k.n; ++n) {
    const long o = static_cast<long>(k.dv[n]) * wx + k.du[n];
    s += k.w[n] * (d[-o] - d[o]);
  }
  const double* h = height + at;
  double t = 0.0;
  for (int n = 0; n < c.n; ++n) {
    const long o = static_cast<long>(c.dv[n]) * wx + c.du[n];
    t += c.w[n] * (h[-o] - h[0]);
  }
  return {s, t, d[0]};
}

// tau1 / tau0 at window cell (i, j): A [ (sum_n k[n] (D(p - o_n) - D(p +
// o_n)) + B D(p)) + sum_n c[n] (h(p - o_n) - h(p)) ], `slope` holding D h
// and `height` the coarse heights over the window (`wx` wide).
ERG_HD float perturbation_at(const double* slope, const double* height, int wx, TapsView k,
                             TapsView c, Params p, int i, int j) {
  const Sums u = sums_at(slope, height, wx, k, c, i, j);
  return static_cast<float>(static_cast<double>(p.a) *
                            ((u.s + static_cast<double>(p.b) * u.d0) + u.t));
}

// tau_y / tau0 at window cell (i, j): A [ sum_n k[n] (P(p - o_n) - P(p +
// o_n)) + sum_n c[n] (h(p - o_n) - h(p)) ], `slope` holding D_perp h (the
// slope across the wind: slope_at with the direction (-ey, ex)) and `c` the
// lateral correction's taps.
ERG_HD float lateral_at(const double* slope, const double* height, int wx, TapsView k, TapsView c,
                        Params p, int i, int j) {
  const Sums u = sums_at(slope, height, wx, k, c, i, j);
  return static_cast<float>(static_cast<double>(p.a) * (u.s + u.t));
}

// The surface wind w under the stress vector tau / tau0 = (1 + tau1) e +
// tau_y e_perp, tau1 and tau_y relative to the undisturbed wind e: turned
// by the stress's angle to e and scaled by the square root of its magnitude
// m (u* ~ sqrt(tau)); the along-wind part clipped at 0. With v = max(1 +
// tau1, 0): w' = (v w + tau_y w_perp) / sqrt(m), m = |(v, tau_y)|, w_perp =
// w turned +90 deg; 0 where m is 0. Flat ground (0, 0) gives w back exactly
// (v = m = 1).
ERG_HD Vec2 surface_wind(float tau1, float tau_y, Vec2 w) {
  const float v = max_of(1.0f + tau1, 0.0f);
  const float m = sqrtf(v * v + tau_y * tau_y);
  const float g = m > 0.0f ? 1.0f / sqrtf(m) : 0.0f;
  return {g * (v * w.x - tau_y * w.y), g * (v * w.y + tau_y * w.x)};
}

}  // namespace erg::shear_stress
