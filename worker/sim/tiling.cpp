// SPDX-License-Identifier: Apache-2.0
#include "sim/tiling.h"

#include "dist/mpi_exchange.h"

namespace erg {

std::unique_ptr<Tiling> make_tiling(const erg::v1::JobSpec& spec, MPI_Comm world, int tiles_x,
                                    int tiles_y) {
  auto t = std::make_unique<Tiling>();
  MPI_Comm_rank(world, &t->rank);
  MPI_Comm_size(world, &t->size);
  const int gnx = static_cast<int>(spec.domain().nx()), gny = static_cast<int>(spec.domain().ny());
  const AvalancheRounds round = t->tiled() ? kTiledRounds : kOneTileRounds;
  const Model whole = make_model(spec, gnx, gny, 0, 0, round);
  t->d = plan_tiles(spec, t->size, tiles_x, tiles_y);
  int dims[2] = {t->d.px, t->d.py}, periods[2] = {1, 1}, coords[2] = {0, 0};
  MPI_Cart_create(world, 2, dims, periods, 0, &t->cart);
  MPI_Cart_coords(t->cart, t->rank, 2, coords);
  t->slab = {t->d.x0(coords[0]), t->d.y0(coords[1]), t->d.nx(coords[0]), t->d.ny(coords[1])};
  MPI_Comm node;
  MPI_Comm_split_type(world, MPI_COMM_TYPE_SHARED, t->rank, MPI_INFO_NULL, &node);
  MPI_Comm_rank(node, &t->place.local_rank);  // the GPU: local_rank % devices
  MPI_Comm_free(&node);
  t->place.x0 = t->slab.x0;
  t->place.y0 = t->slab.y0;
  t->place.nx = t->slab.nx;
  t->place.ny = t->slab.ny;
  t->place.rounds = round;
  if (t->tiled()) {
    const Model tile = make_model(spec, t->slab.nx, t->slab.ny, t->slab.x0, t->slab.y0, round);
    t->exchange = std::make_unique<dist::MpiExchange>(t->cart, t->d, tile.tile, whole.coarse.cx,
                                                      whole.coarse.cy);
    t->place.exchange = t->exchange.get();
  }
  return t;
}

}  // namespace erg
