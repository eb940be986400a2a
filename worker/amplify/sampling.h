// Internal to amplify/: reading coarse snapshot fields at fine positions.
#pragma once

#include <cmath>
#include <vector>

namespace erg::amplify::detail {

inline int wrap(int i, int n) {
  const int r = i % n;
  return r < 0 ? r + n : r;
}

// Bilinear value of a periodic [ny][nx] field (stride components per cell,
// component c) at coarse-cell coordinates (x, y), cell centres at integers.
inline float bilinear(const std::vector<float>& f, int nx, int ny, double x, double y,
                      int stride = 1, int c = 0) {
  const double fx = std::floor(x), fy = std::floor(y);
  const double tx = x - fx, ty = y - fy;
  const int i0 = wrap(static_cast<int>(fx), nx), i1 = wrap(static_cast<int>(fx) + 1, nx);
  const int j0 = wrap(static_cast<int>(fy), ny), j1 = wrap(static_cast<int>(fy) + 1, ny);
  auto at = [&](int i, int j) {
    return static_cast<double>(f[(static_cast<size_t>(j) * nx + i) * stride + c]);
  };
  return static_cast<float>((1 - ty) * ((1 - tx) * at(i0, j0) + tx * at(i1, j0)) +
                            ty * ((1 - tx) * at(i0, j1) + tx * at(i1, j1)));
}

}  // namespace erg::amplify::detail
