// SPDX-License-Identifier: Apache-2.0
// Vegetation: how plant cover v in [0, 1] couples into every transport stage
// ([P19] 5.1 and Fig. 8, [N24] 3.6-3.8). Vegetation is static between
// timeline events; these are the only places it acts, so changing the
// vegetation model means changing this file.
#pragma once

#include "core/hd.h"

namespace erg::vegetation {

// Plants shield sand from the wind: lift scales with (1 - v) [N24 eq. 5].
ERG_HD float lift_factor(float shadow, float v) {
  return (1.0f - shadow) * (1.0f - v);
}

// Probability that a landing slab stays: beta = clamp(sigma + f_S + f_V(v)).
// [P19] 5.1 writes f_V(v) = 1 - v, which would make beta >= 1 on bare ground
// and stop all bouncing; its Fig. 8 ("vegetation decreases the probability of
// bouncing") and [N24]'s code need f_V increasing with v, so f_V(v) = v.
//
// f_S is Werner's step, f_S(0) = p_bedrock and f_S(s > 0) = p_sand, where
// "sand present" means at least one slab. In expected transport a cell can
// hold any fraction of a slab, so f_S ramps from p_bedrock to p_sand as the
// sand thickness grows from 0 to one slab (`sand_fraction` = min(s / eps_S, 1)):
// a film thinner than a slab catches sand like bare rock, as in [W95].
ERG_HD float deposition_probability(float shadow, float sand_fraction, float v, float p_sand,
                                    float p_bedrock) {
  const float f_s = p_bedrock + (p_sand - p_bedrock) * sand_fraction;
  return clamp_to(shadow + f_s + v, 0.0f, 1.0f);
}

// Reptation is triggered by impacts on unvegetated sand: beta_R = 1 - v [P19 5.1].
ERG_HD float reptation_factor(float v) {
  return 1.0f - v;
}

// Abrasion is dampened by cover [P19 5.2].
ERG_HD float abrasion_factor(float v) {
  return 1.0f - v;
}

// Roots hold slopes steeper: tan(repose) interpolates from bare to vegetated
// [N24 3.8, Beakawi Al-Hashemi 2018].
ERG_HD float repose_tan(float v, float tan_bare, float tan_vegetated) {
  return tan_bare + (tan_vegetated - tan_bare) * v;
}

}  // namespace erg::vegetation
