// SPDX-License-Identifier: Apache-2.0
// A 2-vector of floats usable on host and device (wind, gradients).
#pragma once

#include "core/hd.h"

namespace erg {

struct Vec2 {
  float x = 0, y = 0;
};
ERG_HD Vec2 operator+(Vec2 a, Vec2 b) {
  return {a.x + b.x, a.y + b.y};
}
ERG_HD Vec2 operator-(Vec2 a, Vec2 b) {
  return {a.x - b.x, a.y - b.y};
}
ERG_HD Vec2 operator*(float s, Vec2 a) {
  return {s * a.x, s * a.y};
}
ERG_HD float dot(Vec2 a, Vec2 b) {
  return a.x * b.x + a.y * b.y;
}
ERG_HD float length(Vec2 a) {
  return sqrtf(a.x * a.x + a.y * a.y);
}

}  // namespace erg
