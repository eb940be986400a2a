// SPDX-License-Identifier: Apache-2.0
// One field of a halo exchange and the ghost width it needs. Several travel
// together: one message per neighbour and phase carries all of them (the
// halo over an array set of Cabana::Grid).
#pragma once

#include <variant>

#include "core/field.h"
#include "core/units.h"

namespace erg::dist {

// What an exchange does with the ghosts: fill them from their owners (whole,
// or in two halves around work that reads none of them), or sum them into
// their owners (a scatter across tile edges), zeroing them.
enum class GhostOp { kFill, kBeginFill, kFinishFill, kSum };

struct Ghosts {
  std::variant<Field<units_t>*, Field<float>*, Field<double>*> field;
  int width = 0;
  // The field's device copy (same TileGeom layout) when a device packer
  // (dist::HaloPacker, CUDA-aware MPI) moves it; the host field then only
  // names the type and geometry.
  void* device = nullptr;
};

}  // namespace erg::dist
