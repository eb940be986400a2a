// SPDX-License-Identifier: Apache-2.0
// Sand bumps B around plants and obstacles [P19 6, Fig. 13]: sand caught by a
// small obstacle piles up on its windward side and trails in its lee, as a
// nabkha does. Each bump blends two point primitives: a round mound just
// upwind of the obstacle and a half-height tail elongated downwind; bumps
// merge by their maximum. Plants sit at seeded sites in each simulation cell,
// each present with probability equal to the vegetation density, and their
// height is proportional to the density.
#pragma once

#include <vector>

#include "amplify/amplify.h"

namespace erg::amplify {

// B in metres on the output grid of `region` upsampled `upsample` times,
// [region.h * K][region.w * K]. Obstacles add bumps only when
// in.obstacles is not empty.
std::vector<float> sand_bumps(const AmplifyInput& in, const Region& region, int upsample,
                              const AmplifyParams& p);

}  // namespace erg::amplify
