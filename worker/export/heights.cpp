// The exported samples of a layer (see heights_for_export in export.h).
#include <cmath>
#include <string>
#include <vector>

#include "export/export.h"

namespace erg::exporting {

std::vector<float> heights_for_export(const io::Snapshot& snap, Layer layer, const Region& region,
                                      int upsample, int* nx_out, int* ny_out) {
  const int nx = snap.meta.nx, ny = snap.meta.ny;
  const std::size_t n = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  std::vector<float> src(n);
  for (std::size_t k = 0; k < n; ++k) {
    switch (layer) {
      case Layer::kHeight:
        // The ground: bedrock under its sand (README, snapshot contract).
        src[k] = snap.bedrock[k] + snap.sand[k];
        break;
      case Layer::kSand:
        src[k] = snap.sand[k];
        break;
      case Layer::kBedrock:
        src[k] = snap.bedrock[k];
        break;
      case Layer::kVegetation:
        src[k] = snap.vegetation[k];
        break;
    }
  }
  const Region r = region.w > 0 ? region : Region{0, 0, nx, ny};
  const int K = upsample;
  const int onx = r.w * K + 1, ony = r.h * K + 1;
  std::vector<float> out(static_cast<std::size_t>(onx) * static_cast<std::size_t>(ony));
  auto cell = [&](long long x, long long y) {
    x = ((x % nx) + nx) % nx;
    y = ((y % ny) + ny) % ny;
    return src[static_cast<std::size_t>(y) * nx + static_cast<std::size_t>(x)];
  };
  for (int j = 0; j < ony; ++j)
    for (int i = 0; i < onx; ++i) {
      float v;
      if (K == 1) {
        v = cell(r.x0 + i, r.y0 + j);  // exact: the snapshot's own cells
      } else {
        // Sample centre in cell-centre coordinates: cell c's centre is c.
        const double u = r.x0 + (i + 0.5) / K - 0.5, w = r.y0 + (j + 0.5) / K - 0.5;
        const double fu = std::floor(u), fw = std::floor(w);
        const double tu = u - fu, tw = w - fw;
        const auto cu = static_cast<long long>(fu), cw = static_cast<long long>(fw);
        v = static_cast<float>((1 - tw) * ((1 - tu) * cell(cu, cw) + tu * cell(cu + 1, cw)) +
                               tw * ((1 - tu) * cell(cu, cw + 1) + tu * cell(cu + 1, cw + 1)));
      }
      out[static_cast<std::size_t>(j) * onx + i] = v;
    }
  // Amplification hook: worker/amplify/ adds ripples to `out` here (layer
  // kHeight, upsample > 1), on the same (onx x ony) samples.
  *nx_out = onx;
  *ny_out = ony;
  return out;
}

}  // namespace erg::exporting
