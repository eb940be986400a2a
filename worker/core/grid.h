// SPDX-License-Identifier: Apache-2.0
// Geometry of one tile of the toric domain, with a ghost (halo) ring.
//
// A tile owns nx x ny cells whose global coordinates start at (x0, y0) in a
// global domain of gnx x gny cells. Every field of the tile is stored padded
// with `halo` ghost cells on each side, so stencils index neighbours without
// wrapping arithmetic in inner loops; ghosts are filled from their owners
// (periodic wrap on one domain, halo exchange between ranks). Local
// coordinates run from -halo to n + halo - 1.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/hd.h"

namespace erg {

struct TileGeom {
  int nx = 0, ny = 0;    // owned cells
  int halo = 0;          // ghost width on every side
  int pitch = 0;         // elements per stored row (>= nx + 2 halo, padded)
  int x0 = 0, y0 = 0;    // global coordinates of owned cell (0, 0)
  int gnx = 0, gny = 0;  // global domain size
  float cell_m = 1.0f;   // cell edge length l

  ERG_HD int rows() const { return ny + 2 * halo; }
  ERG_HD std::size_t size() const { return static_cast<std::size_t>(rows()) * pitch; }
  // Storage index of local cell (x, y), -halo <= x < nx + halo.
  ERG_HD std::size_t at(int x, int y) const {
    return static_cast<std::size_t>(y + halo) * pitch + static_cast<std::size_t>(x + halo);
  }
  // Global, wrapped linear index of local cell (x, y): the key of random draws.
  ERG_HD std::uint64_t global_index(int x, int y) const {
    int gx = (x0 + x) % gnx;
    if (gx < 0) gx += gnx;
    int gy = (y0 + y) % gny;
    if (gy < 0) gy += gny;
    return static_cast<std::uint64_t>(gy) * static_cast<std::uint64_t>(gnx) +
           static_cast<std::uint64_t>(gx);
  }
};

// Padded row length: a multiple of 16 elements keeps rows 64-byte aligned for
// every element type we store (int64, float).
inline int padded_pitch(int nx, int halo) {
  return (nx + 2 * halo + 15) / 16 * 16;
}

inline TileGeom make_single_tile(int nx, int ny, int halo, float cell_m) {
  TileGeom g;
  g.nx = nx;
  g.ny = ny;
  g.halo = halo;
  g.pitch = padded_pitch(nx, halo);
  g.gnx = nx;
  g.gny = ny;
  g.cell_m = cell_m;
  return g;
}

// The 8 neighbours, in a fixed order used by every stencil. Diagonals have
// distance sqrt(2) cells.
struct Neighbour {
  int dx, dy;
  float dist;
};
inline constexpr float kSqrt2 = 1.41421356237309515f;
// Neighbour k (0..7) in that order. Per-cell math shared with the device uses
// this, not kNeighbours: nvcc cannot index a namespace-scope constexpr array
// in device code, but a constexpr local of a host/device function is fine.
ERG_HD constexpr Neighbour neighbour(int k) {
  constexpr Neighbour table[8] = {{1, 0, 1.0f},  {1, 1, kSqrt2},   {0, 1, 1.0f},  {-1, 1, kSqrt2},
                                  {-1, 0, 1.0f}, {-1, -1, kSqrt2}, {0, -1, 1.0f}, {1, -1, kSqrt2}};
  return table[k];
}
inline constexpr Neighbour kNeighbours[8] = {neighbour(0), neighbour(1), neighbour(2),
                                             neighbour(3), neighbour(4), neighbour(5),
                                             neighbour(6), neighbour(7)};

}  // namespace erg
