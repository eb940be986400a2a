// SPDX-License-Identifier: Apache-2.0
// A job's domain cut into tiles over the ranks of a communicator: the tile
// grid, this rank's tile and how it reaches the others. Used by erg-worker
// and erg-bench.
#pragma once

#include <mpi.h>

#include <memory>

#include "dist/decomposition.h"
#include "dist/exchange.h"
#include "erg/v1/job.pb.h"
#include "io/io.h"
#include "sim/simulation.h"
#include "sim/tile_plan.h"  // plan_tiles: the grid chosen

namespace erg {

struct Tiling {
  MPI_Comm cart = MPI_COMM_NULL;  // periodic Cartesian communicator of the tiles
  int rank = 0, size = 1;
  dist::Decomposition d;
  io::TileSlab slab;  // this rank's tile
  Placement place;    // for the Simulation (holds the exchange below)
  std::unique_ptr<dist::Exchange> exchange;
  bool tiled() const { return size > 1; }
};

// Collective over `world`. One rank: one tile that is the whole torus
// (periodic exchange, per-iteration avalanching rounds). Several: tiles at
// least as wide as the halo, aligned to the coarse wind cells, exchanging
// over MPI, avalanching in kTiledRounds (sim/model.h). Throws
// std::invalid_argument (on every rank alike) for a grid that cannot work.
std::unique_ptr<Tiling> make_tiling(const erg::v1::JobSpec& spec, MPI_Comm world, int tiles_x = 0,
                                    int tiles_y = 0);

}  // namespace erg
