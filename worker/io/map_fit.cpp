// SPDX-License-Identifier: Apache-2.0
// Fitting an input map to the periodic grid: the seam test, the border
// cross-fade and bilinear resampling on the torus (see io.h).
#include <algorithm>
#include <cmath>
#include <vector>

#include "io/io.h"

namespace erg::io {

namespace {
double at(const Map& m, int x, int y) {
  return m.values[static_cast<std::size_t>(y) * static_cast<std::size_t>(m.nx) +
                  static_cast<std::size_t>(x)];
}
}  // namespace

Seam seam_of(const Map& m, int axis) {
  Seam s;
  const int n = axis == 0 ? m.nx : m.ny;  // along the axis
  const int k = axis == 0 ? m.ny : m.nx;  // across it
  if (n < 2) return s;
  auto v = [&](int i, int j) { return axis == 0 ? at(m, i, j) : at(m, j, i); };
  double jump = 0, inner = 0;
  for (int j = 0; j < k; ++j) {
    jump += std::fabs(v(n - 1, j) - v(0, j));
    for (int i = 0; i + 1 < n; ++i) inner += std::fabs(v(i + 1, j) - v(i, j));
  }
  s.jump = jump / k;
  s.interior = inner / (static_cast<double>(k) * (n - 1));
  return s;
}

double range_of(const Map& m) {
  if (m.values.empty()) return 0;
  const auto [lo, hi] = std::minmax_element(m.values.begin(), m.values.end());
  return *hi - *lo;
}

void blend_borders(Map& m, int wx, int wy) {
  // Columns, then rows: the corners get both blends, which keeps them
  // consistent across both seams.
  wx = std::min(wx, m.nx / 2);
  wy = std::min(wy, m.ny / 2);
  if (wx > 0) {
    const Map src = m;
    for (int y = 0; y < m.ny; ++y)
      for (int d = 0; d < wx; ++d) {
        const double a = 0.5 + 0.5 * d / wx;
        const int l = d, r = m.nx - 1 - d;
        m.values[static_cast<std::size_t>(y) * m.nx + l] =
            a * at(src, l, y) + (1 - a) * at(src, r, y);
        m.values[static_cast<std::size_t>(y) * m.nx + r] =
            a * at(src, r, y) + (1 - a) * at(src, l, y);
      }
  }
  if (wy > 0) {
    const Map src = m;
    for (int d = 0; d < wy; ++d) {
      const double a = 0.5 + 0.5 * d / wy;
      const int b = d, t = m.ny - 1 - d;
      for (int x = 0; x < m.nx; ++x) {
        m.values[static_cast<std::size_t>(b) * m.nx + x] =
            a * at(src, x, b) + (1 - a) * at(src, x, t);
        m.values[static_cast<std::size_t>(t) * m.nx + x] =
            a * at(src, x, t) + (1 - a) * at(src, x, b);
      }
    }
  }
}

Map resample_periodic(const Map& m, int nx, int ny) {
  if (m.nx == nx && m.ny == ny) return m;
  Map out = m;
  out.nx = nx;
  out.ny = ny;
  out.values.assign(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), 0.0);
  const double sx = static_cast<double>(m.nx) / nx, sy = static_cast<double>(m.ny) / ny;
  for (int y = 0; y < ny; ++y) {
    // Cell centre y + 1/2 in map pixel units, relative to pixel centres.
    const double fy = (y + 0.5) * sy - 0.5;
    const double fly = std::floor(fy);
    const double ty = fy - fly;
    const int y0 = ((static_cast<int>(fly) % m.ny) + m.ny) % m.ny, y1 = (y0 + 1) % m.ny;
    for (int x = 0; x < nx; ++x) {
      const double fx = (x + 0.5) * sx - 0.5;
      const double flx = std::floor(fx);
      const double tx = fx - flx;
      const int x0 = ((static_cast<int>(flx) % m.nx) + m.nx) % m.nx, x1 = (x0 + 1) % m.nx;
      out.values[static_cast<std::size_t>(y) * nx + x] =
          (1 - ty) * ((1 - tx) * at(m, x0, y0) + tx * at(m, x1, y0)) +
          ty * ((1 - tx) * at(m, x0, y1) + tx * at(m, x1, y1));
    }
  }
  return out;
}

}  // namespace erg::io
