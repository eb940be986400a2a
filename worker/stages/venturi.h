// SPDX-License-Identifier: Apache-2.0
// Venturi effect: wind accelerates with altitude, v = a (1 + k_V h)
// ([P19] 4.2, [N24] eq. 1). The factor is clamped at 0 so that terrain far
// below the datum (h < -1/k_V) calms the wind instead of reversing it.
#pragma once

#include "core/hd.h"
#include "core/vec2.h"

namespace erg::venturi {

ERG_HD Vec2 wind(Vec2 a, float h_m, float k) {
  const float f = max_of(1.0f + k * h_m, 0.0f);
  return f * a;
}

}  // namespace erg::venturi
