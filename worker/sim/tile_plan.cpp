// SPDX-License-Identifier: Apache-2.0
#include "sim/tile_plan.h"

#include "sim/model.h"

namespace erg {

dist::Decomposition plan_tiles(const erg::v1::JobSpec& spec, int ranks, int tiles_x, int tiles_y) {
  const int gnx = static_cast<int>(spec.domain().nx()), gny = static_cast<int>(spec.domain().ny());
  const AvalancheRounds round = ranks > 1 ? kTiledRounds : kOneTileRounds;
  const Model whole = make_model(spec, gnx, gny, 0, 0, round);
  // Neighbours' ghosts come from one tile: tiles at least as wide as the
  // halo; each coarse wind cell lies in one tile.
  return dist::decompose(gnx, gny, ranks, ranks > 1 ? whole.tile.halo : 1, tiles_x, tiles_y,
                         whole.coarse.cx, whole.coarse.cy);
}

}  // namespace erg
