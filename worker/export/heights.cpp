// SPDX-License-Identifier: Apache-2.0
// The exported samples of a layer (see heights_for_export in export.h) and
// their amplified form (amplified_heights).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "amplify/amplify.h"
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
        src[k] = snap[fields::kBedrock][k] + snap[fields::kSand][k];
        break;
      case Layer::kSand:
        src[k] = snap[fields::kSand][k];
        break;
      case Layer::kBedrock:
        src[k] = snap[fields::kBedrock][k];
        break;
      case Layer::kVegetation:
        src[k] = snap[fields::kVegetation][k];
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
  *nx_out = onx;
  *ny_out = ony;
  return out;
}

std::vector<float> amplified_heights(const std::string& path, const Region& region, int upsample,
                                     int* nx_out, int* ny_out) {
  erg::v1::JobSpec spec;
  const amplify::AmplifyInput in = amplify::input_from_snapshot(path, spec);
  const Region r = region.w > 0 ? region : Region{0, 0, in.nx, in.ny};
  // One more cell east and north gives the shared extra column and row; a
  // region spanning the torus is periodic, so its extra samples wrap.
  const amplify::Region ar{r.x0, r.y0, std::min(r.w + 1, in.nx), std::min(r.h + 1, in.ny)};
  const amplify::AmplifiedLayers a = amplify::amplify_layers(in, ar, upsample, spec.amplify());
  const int onx = r.w * upsample + 1, ony = r.h * upsample + 1;
  std::vector<float> out(static_cast<std::size_t>(onx) * static_cast<std::size_t>(ony));
  // Fine sample i of the amplified grid and sample i of heights_for_export
  // both stand at x0 + (i + 1/2) / K cells.
  for (int j = 0; j < ony; ++j)
    for (int i = 0; i < onx; ++i)
      out[static_cast<std::size_t>(j) * onx + i] =
          a.height[static_cast<std::size_t>(j % a.ny) * a.nx + static_cast<std::size_t>(i % a.nx)];
  *nx_out = onx;
  *ny_out = ony;
  return out;
}

}  // namespace erg::exporting
