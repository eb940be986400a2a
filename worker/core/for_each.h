// SPDX-License-Identifier: Apache-2.0
// The CPU half of the execution layer that runs a stages/ body over a tile
// (the GPU half is backend/cuda/for_each.cuh): rows in parallel, statically
// scheduled, each row a plain loop over x that the compiler can vectorise
// when the body is a row kernel with restrict-qualified outputs. Any body
// whose cells are independent gives the same bits for every thread count.
#pragma once

#include <cstddef>

#include "core/grid.h"

namespace erg {

// row(y) for every owned row y of g.
template <class Row>
void for_each_row(int threads, const TileGeom& g, Row&& row) {
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int y = 0; y < g.ny; ++y) row(y);
}

// cell(x, y, i) for every owned cell, i its storage index.
template <class Cell>
void for_each_cell(int threads, const TileGeom& g, Cell&& cell) {
  for_each_row(threads, g, [&](int y) {
    for (int x = 0; x < g.nx; ++x) cell(x, y, g.at(x, y));
  });
}

}  // namespace erg
