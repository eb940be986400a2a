// SPDX-License-Identifier: Apache-2.0
// Internal to amplify/: reading coarse snapshot fields at fine positions.
#pragma once

#include <cmath>
#include <vector>

namespace erg::amplify::detail {

inline int wrap(int i, int n) {
  const int r = i % n;
  return r < 0 ? r + n : r;
}

// Bilinear value of a periodic [ny][nx] field (stride components per cell,
// component c) at cell coordinates (x, y), cell centres at integers; summed
// in double, returned in the field's type.
template <typename T>
inline T bilinear(const std::vector<T>& f, int nx, int ny, double x, double y, int stride = 1,
                  int c = 0) {
  const double fx = std::floor(x), fy = std::floor(y);
  const double tx = x - fx, ty = y - fy;
  const int i0 = wrap(static_cast<int>(fx), nx), i1 = wrap(static_cast<int>(fx) + 1, nx);
  const int j0 = wrap(static_cast<int>(fy), ny), j1 = wrap(static_cast<int>(fy) + 1, ny);
  auto at = [&](int i, int j) {
    return static_cast<double>(f[(static_cast<size_t>(j) * nx + i) * stride + c]);
  };
  return static_cast<T>((1 - ty) * ((1 - tx) * at(i0, j0) + tx * at(i1, j0)) +
                        ty * ((1 - tx) * at(i0, j1) + tx * at(i1, j1)));
}

// Catmull-Rom bicubic value of a periodic [ny][nx] field at cell-centre
// coordinates (x, y): C1-continuous, so a hillshade of the upsampled terrain
// shows no facets at the coarse cells (bilinear would). It may overshoot
// between cells; callers clamp where a sign matters (sand >= 0).
inline float bicubic(const std::vector<float>& f, int nx, int ny, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const double tx = x - fx, ty = y - fy;
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  auto weights = [](double t, double w[4]) {
    const double t2 = t * t, t3 = t2 * t;
    w[0] = 0.5 * (-t3 + 2 * t2 - t);
    w[1] = 0.5 * (3 * t3 - 5 * t2 + 2);
    w[2] = 0.5 * (-3 * t3 + 4 * t2 + t);
    w[3] = 0.5 * (t3 - t2);
  };
  double wx[4], wy[4];
  weights(tx, wx);
  weights(ty, wy);
  double v = 0;
  for (int b = 0; b < 4; ++b) {
    const size_t row = static_cast<size_t>(wrap(iy - 1 + b, ny)) * nx;
    double r = 0;
    for (int a = 0; a < 4; ++a) r += wx[a] * static_cast<double>(f[row + wrap(ix - 1 + a, nx)]);
    v += wy[b] * r;
  }
  return static_cast<float>(v);
}

}  // namespace erg::amplify::detail
