// SPDX-License-Identifier: Apache-2.0
// The GPU half of the execution layer (the CPU half is core/for_each.h): a
// stages/ body run as a kernel, one thread per owned cell. The body is an
// extended __device__ lambda (--extended-lambda) that captures the device
// pointers and parameters by value.
#pragma once

#include <cstddef>

#include "backend/cuda/cuda_backend.h"

namespace erg::gpu {

template <class Cell>
__global__ void for_each_cell_kernel(TileGeom g, Cell cell) {
  int x, y;
  if (!owned_cell(g, x, y)) return;
  cell(x, y, g.at(x, y));
}

// cell(x, y, i) for every owned cell of g, i its storage index; `what` names
// the launch in errors.
template <class Cell>
void for_each_cell(const TileGeom& g, const char* what, Cell cell) {
  const Launch l = owned_cells(g);
  for_each_cell_kernel<<<l.grid, l.block>>>(g, cell);
  check_launch(what);
}

}  // namespace erg::gpu
