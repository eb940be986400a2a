// Everything a step needs from the job spec, resolved once into plain values
// (radians to tangents, metres to units and cells) so kernels receive small
// POD structs by value.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/grid.h"
#include "erg/v1/job.pb.h"
#include "stages/saltation.h"
#include "stages/wind_shadow.h"
#include "stages/wind_warping.h"

namespace erg {

// The coarse grid of the wind-warping smoothing (stages/wind_warping.h).
struct CoarseGrid {
  int cx = 1, cy = 1;          // fine cells per coarse cell along x, y
  int nx = 0, ny = 0;          // coarse cells
  double lx_m = 0, ly_m = 0;   // domain extent
  double sigma_m[2] = {0, 0};  // Gaussian sigma of the large and small scales
};

// Avalanching iterations per round when tiles exchange over MPI. After the
// first steps relax the initial sand, avalanching moves sand in one or two
// iterations per step and the next finds nothing to move, so a round of 4
// usually ends the step's avalanching with one logical or and no refill. Its
// halo, 2 * 4 + 1 = 9 cells, is what the tiles exchange before reptation
// (with all of N = 50 iterations in one round it would be 101). Execution
// only: results are identical for any round length.
constexpr int kTiledAvalancheRound = 4;

struct Model {
  TileGeom tile;  // the tile this process owns, with its halo
  std::uint64_t seed = 0;
  bool stochastic = false;
  float venturi_k = 0;
  wind_warping::Params warp{};
  CoarseGrid coarse;
  wind_shadow::Params shadow{};
  saltation::Params saltation{};
  float reptation_k = 0;
  // tan(repose) * l: metres of height difference allowed per cell of distance.
  float tan_l_sand = 0, tan_l_vegetated = 0, tan_l_bedrock = 0;
  int avalanche_iterations = 0;
  float kc = 1, kc_damped = 0.5f;
  int bedrock_iterations = 0;
  bool bedrock_to_sand = false;
  double time_step_days = 0;
  // Execution, not physics: visit every cell in every avalanching iteration
  // instead of only where something can change (tests compare the two).
  bool avalanche_everywhere = false;

  // Ghost cells each stage reads (DESIGN.md section 4).
  int halo_shadow() const { return shadow.steps + 2; }
  int halo_saltation() const {  // hop reach + bilinear footprint
    return static_cast<int>(std::ceil(saltation.max_hop_m / tile.cell_m)) + 2;
  }
  // Avalanching iterations between two refills of the avalanching layer's
  // ghosts: 1 on one tile (a refill is a local copy, a wide halo only adds
  // work); kTiledAvalancheRound with several; 0 means all of a step's
  // iterations in one round (one exchange whatever their number, but a halo
  // of 2N + 1 cells, computed redundantly by both neighbours).
  int avalanche_round = 0;
  int avalanche_round_for(int iterations) const {
    return avalanche_round <= 0 ? iterations : std::min(avalanche_round, iterations);
  }
  // Ghost-zone expansion: a round of R iterations runs inside a halo of 2R
  // cells (two cells per iteration); reptation, just before, needs one more.
  int halo_avalanche() const {
    return 2 * avalanche_round_for(std::max(avalanche_iterations, bedrock_iterations));
  }
};

// Resolves a defaults-filled, validated spec for a tile of `nx x ny` owned
// cells at global offset (x0, y0); the halo is chosen to cover every stage.
// avalanche_round: see Model.
Model make_model(const erg::v1::JobSpec& spec, int nx, int ny, int x0, int y0,
                 int avalanche_round = 1);

}  // namespace erg
