// SPDX-License-Identifier: Apache-2.0
// The overview pyramid of a run's terrain (io.h OverviewPyramid), computed
// where the cells are: each rank reduces its own tile, and the blocks that
// straddle tiles are completed by their owners from the partial sums of the
// tiles they overlap. Nothing of the size of the domain meets on one rank:
// rank 0 assembles only the level a preview needs (gather_overview_level).
//
// Exactness. A block's mean is computed from exact integer sums of its cells:
// bedrock and sand in units of 2^-32 m (every float32 height a snapshot holds
// is a whole number of them: core/units.h), vegetation in units of 2^-64
// (densities above 2^-41 exactly). Integer sums do not depend on the order
// they are added in, so a level is bitwise the same for any tiling, rank
// count and thread count; the division by the block's cell count happens once,
// on the block's owner. A block's owner is the tile holding its first cell
// (lowest x and y).
#pragma once

#include <mpi.h>

#include <functional>

#include "dist/decomposition.h"
#include "io/io.h"

namespace erg {

// Rows [y0, y1) of the tile's owned cells of one layer (0 bedrock, 1 sand,
// 2 vegetation), row-major, float32 as written to snapshots.
using TerrainRows = std::function<void(int layer, int y0, int y1, float* out)>;

// Rows of the tile read at once: the terrain is reduced a band at a time, so
// a snapshot holds no copy of the tile's layers (3 x 4 bytes x 64 rows).
inline constexpr int kOverviewBandRows = 64;

// The lowest and highest ground, bedrock + sand in float32 metres (as a
// reader of the layers adds them), over the whole domain: min and max are
// exact, so a reduction gives the same bits on any tiling.
struct GroundRange {
  float min_m = 0, max_m = 0;
};

// Levels 1 to io::overview_levels(gnx, gny) of the tiles' layers. Collective
// over `cart`, the periodic Cartesian communicator of the tiling `d` (one
// rank: one tile that is the whole domain). Each level holds the blocks this
// rank owns (possibly none). With `ground`, the domain's ground range too,
// from the same read of the rows, on every rank.
io::OverviewPyramid overview_pyramid(MPI_Comm cart, const dist::Decomposition& d,
                                     const TerrainRows& rows, GroundRange* ground = nullptr);

// Collective: the whole of level `level` on rank 0 of `cart` (empty
// elsewhere), from each rank's blocks of it: `pyramid` for level >= 1, the
// tile's cells for level 0 (only when the whole domain fits a preview, so
// at most io::kPreviewMaxPx^2 cells meet on rank 0).
io::OverviewLevel gather_overview_level(MPI_Comm cart, const dist::Decomposition& d,
                                        const io::OverviewPyramid& pyramid, int level,
                                        const TerrainRows& rows);

}  // namespace erg
