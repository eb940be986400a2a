// SPDX-License-Identifier: Apache-2.0
// The cells a halo exchange of width w touches on a tile: the ghosts within
// w of the tile's edges and the owned cells within w of them (the owners the
// ghosts of neighbours read, and that sums add into). Together they form a
// frame 2w wide astride the tile's edge. A device backend stages only this
// frame through host memory for an exchange (pack on the device, copy,
// unpack into the host field the exchange works on, and back), not whole
// fields: for an 8192^2 tile and w = 3, 0.3% of its cells.
//
// Cells are numbered row by row: the full rows along the bottom edge, then
// the left and right strips of the rows between, then the full rows along
// the top edge. The same numbering packs on the device and unpacks on the
// host (ERG_HD), so the two agree by construction.
#pragma once

#include <cstddef>

#include "core/field.h"
#include "core/grid.h"
#include "core/hd.h"

namespace erg::dist {

struct HaloFrame {
  int nx = 0, ny = 0, w = 0;

  ERG_HD int row_cells() const { return nx + 2 * w; }
  // Rows between the two bands whose middle is not in the frame.
  ERG_HD int inner_rows() const { return ny > 2 * w ? ny - 2 * w : 0; }
  // Frame cells of such a row: both strips, or the whole row if they meet.
  ERG_HD int inner_row_cells() const { return nx > 2 * w ? 4 * w : row_cells(); }
  // Full rows of the bottom band (all rows when the bands meet).
  ERG_HD int bottom_rows() const { return inner_rows() > 0 ? 2 * w : ny + 2 * w; }
  ERG_HD int top_rows() const { return inner_rows() > 0 ? 2 * w : 0; }

  ERG_HD std::size_t size() const {
    if (w <= 0) return 0;
    return static_cast<std::size_t>(bottom_rows() + top_rows()) * row_cells() +
           static_cast<std::size_t>(inner_rows()) * inner_row_cells();
  }

  // Whether local cell (x, y) is owned (else a ghost).
  ERG_HD bool owned(int x, int y) const { return x >= 0 && x < nx && y >= 0 && y < ny; }

  // Local cell (x, y) of frame cell i < size().
  ERG_HD void cell(std::size_t i, int& x, int& y) const {
    const std::size_t row = static_cast<std::size_t>(row_cells());
    const std::size_t bottom = static_cast<std::size_t>(bottom_rows()) * row;
    if (i < bottom) {
      y = -w + static_cast<int>(i / row);
      x = -w + static_cast<int>(i % row);
      return;
    }
    i -= bottom;
    const std::size_t inner_row = static_cast<std::size_t>(inner_row_cells());
    const std::size_t inner = static_cast<std::size_t>(inner_rows()) * inner_row;
    if (i < inner) {
      y = w + static_cast<int>(i / inner_row);
      const int c = static_cast<int>(i % inner_row);
      if (nx > 2 * w)
        x = c < 2 * w ? c - w : nx - w + (c - 2 * w);
      else
        x = c - w;
      return;
    }
    i -= inner;
    y = ny - w + static_cast<int>(i / row);
    x = -w + static_cast<int>(i % row);
  }
};

// The frame of field f (whose halo must be at least w wide) into out[0,
// size()) and back. Host versions; the CUDA backend has the kernels.
template <class T>
void pack_frame(const Field<T>& f, const HaloFrame& fr, T* out) {
  for (std::size_t i = 0; i < fr.size(); ++i) {
    int x, y;
    fr.cell(i, x, y);
    out[i] = f(x, y);
  }
}

// ghosts_only: only the frame's ghost cells are written (after a fill,
// whose owned cells are unchanged: dist/halo_path.h).
template <class T>
void unpack_frame(const T* in, const HaloFrame& fr, Field<T>& f, bool ghosts_only = false) {
  for (std::size_t i = 0; i < fr.size(); ++i) {
    int x, y;
    fr.cell(i, x, y);
    if (!(ghosts_only && fr.owned(x, y))) f(x, y) = in[i];
  }
}

}  // namespace erg::dist
