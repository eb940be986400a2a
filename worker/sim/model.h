// SPDX-License-Identifier: Apache-2.0
// Everything a step needs from the job spec, resolved once into plain values
// (radians to tangents, metres to units and cells) so kernels receive small
// POD structs by value.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/fields.h"
#include "core/grid.h"
#include "erg/v1/job.pb.h"
#include "stages/echo_dunes.h"
#include "stages/saltation.h"
#include "stages/shear_stress.h"
#include "stages/wind_shadow.h"
#include "stages/wind_warping.h"

namespace erg {

// How a step's avalanching iterations are grouped into rounds. A round of R
// iterations starts from layers whose ghosts are filled 2R + 1 cells wide
// and needs no exchange inside (ghost-zone expansion, docs/design.md
// "Tiling");
// a new round refills the ghosts. Execution only: every grouping gives the
// same results, bit for bit (tests/sim/test_exactness.cpp).
struct AvalancheRounds {
  int length = 1;  // iterations of the first round; 0: all of them in one
  int later = 1;   // iterations of each later round; 0: all the others in one

  struct Round {
    int first = 1, length = 1;  // iterations [first, first + length)
  };
  // The round holding iteration `it` (1-based) of `n`.
  Round of(int it, int n) const {
    const int r = length <= 0 ? n : std::min(length, n);
    if (it <= r) return {1, r};
    if (later <= 0) return {r + 1, n - r};
    const int first = r + 1 + (it - r - 1) / later * later;
    return {first, std::min(later, n - first + 1)};
  }
  int first_length(int n) const { return of(1, n).length; }
  int widest(int n) const {
    if (n <= 0) return 0;
    const int r = first_length(n);
    return std::max(r, later <= 0 ? n - r : std::min(later, n - r));
  }
};

// One tile refills its ghosts, a local copy, before every iteration: a wide
// halo would only add work.
constexpr AvalancheRounds kOneTileRounds{1, 1};
// Several tiles: a first round of 4, then rounds of 46. After the first
// steps relax the initial sand, avalanching moves sand in one or two
// iterations per step and the next finds nothing to move, so most steps end
// after the first round with one logical or: the tiles exchange a 9-cell
// halo before reptation. When sand keeps moving, each later round refills
// a halo of 2 x 46 + 1 = 93 cells once. Avalanching iterates until the
// terrain settles or model.avalanche_iterations (a cap a job may raise to
// thousands), so the later rounds have a fixed length instead of "the
// rest in one", which would size the halo by the cap: 46 keeps the
// halo and the exchanges of a step that settles within [N24]'s typical 50
// iterations what they were when 50 was the budget (4 + 46).
constexpr AvalancheRounds kTiledRounds{4, 46};

struct Model {
  TileGeom tile;  // the tile this process owns, with its halo
  std::uint64_t seed = 0;
  bool stochastic = false;
  float venturi_k = 0;
  wind_warping::Params warp{};
  CoarseGrid coarse;
  shear_stress::Params shear{};  // physical modes (stages/shear_stress.h)
  wind_shadow::Params shadow{};
  echo_dunes::Params echo{};
  saltation::Params saltation{};
  float reptation_k = 0;
  // tan(repose) * l: metres of height difference allowed per cell of distance.
  float tan_l_sand = 0, tan_l_vegetated = 0, tan_l_bedrock = 0;
  // model.repose ISOTROPIC: each donor's tangent is scaled for the direction
  // it faces (avalanching::facing); NEIGHBOUR_PAIRS: [N24] eq. 9 as written.
  bool repose_isotropic = false;
  int avalanche_iterations = 0;
  float kc = 1, kc_damped = 0.5f;
  int bedrock_iterations = 0;
  bool bedrock_to_sand = false;
  double time_step_days = 0;
  // Execution, not physics: visit every cell in every avalanching iteration
  // instead of only where something can change (tests compare the two).
  bool avalanche_everywhere = false;

  // Ghost cells each stage reads (docs/design.md, "Tiling").
  // (The echo-dune search reads the same heights, nearest neighbour.)
  int halo_shadow() const { return std::max(shadow.steps, echo.on ? echo.steps : 0) + 2; }
  int halo_saltation() const {  // hop reach + bilinear footprint
    return static_cast<int>(std::ceil(saltation.max_hop_m / tile.cell_m)) + 2;
  }
  AvalancheRounds rounds;
  // Ghost-zone expansion: a round of R iterations runs inside a halo of 2R
  // cells (two cells per iteration); reptation, just before, needs one more.
  // The first round's ghosts come with the exchange before reptation; the
  // halo is allocated for the widest round.
  int halo_avalanche_first() const {
    return 2 * rounds.first_length(std::max(avalanche_iterations, bedrock_iterations));
  }
  int halo_avalanche() const {
    return 2 * std::max(rounds.widest(avalanche_iterations), rounds.widest(bedrock_iterations));
  }
  // The ghost cells a field must have filled for the stages that read them
  // (its registry Reach, core/fields.h).
  int ghost_width(fields::Reach r) const {
    switch (r) {
      case fields::Reach::kNone:
        return 0;
      case fields::Reach::kShadow:
        return halo_shadow();
      case fields::Reach::kSaltation:
        return halo_saltation();
      case fields::Reach::kReptation:
        return halo_avalanche_first() + 1;
      case fields::Reach::kAvalanche:
        return halo_avalanche() + 1;
      case fields::Reach::kWhole:
        return tile.halo;
    }
    return tile.halo;
  }
};

// Resolves a defaults-filled, validated spec for a tile of `nx x ny` owned
// cells at global offset (x0, y0); the halo is chosen to cover every stage.
Model make_model(const erg::v1::JobSpec& spec, int nx, int ny, int x0, int y0,
                 AvalancheRounds rounds = kOneTileRounds);

}  // namespace erg
