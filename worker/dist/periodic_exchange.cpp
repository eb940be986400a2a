// SPDX-License-Identifier: Apache-2.0
#include <cstring>

#include "dist/exchange.h"

namespace erg::dist {

template <class T>
void fill_periodic(Field<T>& f, int width) {
  const TileGeom& g = f.geom();
  const int w = width < g.halo ? width : g.halo;
  if (w <= 0) return;
  // Columns first, on owned rows; then whole ghost rows copy owned rows
  // (which now carry their column ghosts). Modulo handles halos wider than
  // the tile on tiny domains. What is already there is not written again
  // (copy_changed): the ghosts of a zero layer stay in untouched pages.
  const std::size_t span = sizeof(T) * static_cast<size_t>(w);
  for (int y = 0; y < g.ny; ++y) {
    T* r = f.row(y);
    if (w <= g.nx) {
      copy_changed(r - w, r + g.nx - w, span);
      copy_changed(r + g.nx, r, span);
      continue;
    }
    for (int x = -w; x < 0; ++x) r[x] = r[((x % g.nx) + g.nx) % g.nx];
    for (int x = g.nx; x < g.nx + w; ++x) r[x] = r[x % g.nx];
  }
  for (int y = -w; y < g.ny + w; ++y) {
    if (y >= 0 && y < g.ny) continue;
    const int src = ((y % g.ny) + g.ny) % g.ny;
    copy_changed(f.row(y) - w, f.row(src) - w, sizeof(T) * static_cast<size_t>(g.nx + 2 * w));
  }
}

template <class T>
void sum_periodic(Field<T>& f, int width) {
  const TileGeom& g = f.geom();
  const int w = width < g.halo ? width : g.halo;
  for (int y = -w; y < g.ny + w; ++y) {
    const bool ghost_row = y < 0 || y >= g.ny;
    const int oy = ((y % g.ny) + g.ny) % g.ny;
    for (int x = -w; x < g.nx + w; ++x) {
      if (!ghost_row && x >= 0 && x < g.nx) {
        x = g.nx - 1;  // skip the owned span
        continue;
      }
      T& v = f(x, y);
      if (v != T{}) {
        f(((x % g.nx) + g.nx) % g.nx, oy) += v;
        v = T{};
      }
    }
  }
}

template void fill_periodic(Field<units_t>&, int);
template void fill_periodic(Field<float>&, int);
template void sum_periodic(Field<units_t>&, int);
template void sum_periodic(Field<float>&, int);
template void fill_periodic(Field<double>&, int);
template void sum_periodic(Field<double>&, int);

// The whole torus is this tile: the window wraps onto its own cells.
void PeriodicExchange::coarse_window(const std::vector<double>& mine, int tcnx, int tcny, int hx,
                                     int hy, std::vector<double>& window) {
  const int wx = tcnx + 2 * hx, wy = tcny + 2 * hy;
  window.resize(static_cast<size_t>(wx) * wy);
  for (int j = 0; j < wy; ++j) {
    const int sy = ((j - hy) % tcny + tcny) % tcny;
    for (int i = 0; i < wx; ++i) {
      const int sx = ((i - hx) % tcnx + tcnx) % tcnx;
      window[static_cast<size_t>(j) * wx + i] = mine[static_cast<size_t>(sy) * tcnx + sx];
    }
  }
}

// A local copy: the first half of a split fill does it all.
void PeriodicExchange::ghosts(GhostOp op, std::span<const Ghosts> fields) {
  if (op == GhostOp::kFinishFill) return;
  for (const Ghosts& g : fields)
    std::visit(
        [&](auto* f) {
          if (op == GhostOp::kSum)
            sum_periodic(*f, g.width);
          else
            fill_periodic(*f, g.width);
        },
        g.field);
}

}  // namespace erg::dist
