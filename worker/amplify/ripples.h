// SPDX-License-Identifier: Apache-2.0
// Wind ripples R [P19 6] by the Nishimori-Ouchi model as Onoue & Nishita run
// it [ON00 2(1)], on the upsampled (fine) grid. Each iteration:
//   saltation: every cell lifts q (times its mobility) and drops it a hop
//     L = L0 + b H downwind, L0 proportional to the local wind speed;
//   reptation splash [A87]: the saltating grains rain in at a shallow impact
//     angle theta; a cell takes 1 + tan(alpha) / tan(theta) of the flat-bed
//     impacts (alpha its slope rising downwind, none in the impact shadow of
//     a lee face steeper than theta) and each impact pushes grains a short
//     hop downwind: stoss faces are stripped, the lee steepens;
//   creep: diffusion, H += D (sum of the 4 neighbours / 6 + sum of the 4
//     diagonals / 12 - H) (Nishimori & Ouchi's relaxation by gravity).
// From seeded noise, H grows into ripples perpendicular to the wind whose
// wavelength grows with L0 (hence with the wind speed). Each iteration sees
// one wind of the recent history, picked by a golden-ratio sequence so that
// alternating winds alternate quickly relative to ripple growth.
#pragma once

#include <cstdint>
#include <vector>

#include "amplify/amplify.h"

namespace erg::amplify {

// The fine grid the ripple model runs on, periodic in both directions.
struct RippleGrid {
  int nx = 0, ny = 0;
  std::vector<float> mobility;  // [0, 1]: open sand 1; shadow, vegetation, bare rock 0
  std::vector<float> wind;      // local wind now, m/s, [ny][nx][2]
  // Seeding: fine cell (i, j) is global fine cell (gx0 + i, gy0 + j) modulo
  // (gnx, gny), so the initial noise depends only on the place and the seed.
  int gx0 = 0, gy0 = 0, gnx = 1, gny = 1;
  std::uint64_t seed = 1;
};

// The past winds as a turn and a gain applied to the local wind "now"; one
// per history entry (oldest first).
struct PastWind {
  float cos_turn = 1, sin_turn = 0, gain = 1;
};
std::vector<PastWind> past_winds(const std::vector<Vec2>& wind_history);

// Ripple relief in metres, [ny][nx]: the model's H scaled so that its
// standard deviation over open sand is p.ripple_height_m, times the mobility
// (no ripples in wind shadow, under plants or on bare rock [P19 6]).
std::vector<float> ripple_relief(const RippleGrid& g, const std::vector<PastWind>& winds,
                                 const AmplifyParams& p);

}  // namespace erg::amplify
