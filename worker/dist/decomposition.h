// SPDX-License-Identifier: Apache-2.0
// Partition of the toric domain into a Px x Py Cartesian grid of tiles.
//
// Tiles along an axis are ceil(n / p) cells (rounded up to the alignment),
// the last one the remainder, so
// every tile but the last of a row or column has the same size and is one
// HDF5 chunk of the snapshot files. Rank r of the periodic Cartesian
// communicator owns tile (i, j) = its Cartesian coordinates.
#pragma once

#include <string>

namespace erg::dist {

struct Decomposition {
  int gnx = 0, gny = 0;          // global domain
  int px = 1, py = 1;            // tiles along x, y
  int chunk_x = 0, chunk_y = 0;  // ceil(gnx / px), ceil(gny / py)

  int x0(int i) const { return i * chunk_x; }
  int nx(int i) const { return i + 1 < px ? chunk_x : gnx - (px - 1) * chunk_x; }
  int y0(int j) const { return j * chunk_y; }
  int ny(int j) const { return j + 1 < py ? chunk_y : gny - (py - 1) * chunk_y; }
  int min_tile_x() const { return nx(px - 1); }  // the last tile is the smallest
  int min_tile_y() const { return ny(py - 1); }
};

// Chooses the grid for `ranks` tiles: the user's px x py when both are > 0
// (their product must be `ranks`), otherwise the factorisation of `ranks`
// whose tiles are closest to square. Throws std::invalid_argument with a
// clear message when no grid gives every tile at least `min_tile` cells along
// each axis (the widest halo a stage reads), or when a tile would be empty.
// Tile sizes are rounded up to multiples of align_x, align_y (the coarse
// cells of the wind warping, so that each coarse cell lies in one tile).
Decomposition decompose(int gnx, int gny, int ranks, int min_tile, int px = 0, int py = 0,
                        int align_x = 1, int align_y = 1);

// Parses "PXxPY" (e.g. "3x2"); throws std::invalid_argument naming the text.
void parse_tiles(const std::string& text, int& px, int& py);

}  // namespace erg::dist
