// SPDX-License-Identifier: Apache-2.0
// HaloFrame: the cells a device backend stages through the host for a halo
// exchange of width w are exactly the ghosts within w and the owned cells
// within w of the edge, each once, and pack/unpack round-trip them. No MPI
// (test_halo.cpp runs the staged exchanges under mpirun).
#include <gtest/gtest.h>

#include <cstdint>
#include <set>
#include <utility>
#include <vector>

#include "dist/halo_frame.h"

namespace erg::dist {
namespace {

bool in_frame(int nx, int ny, int w, int x, int y) {
  const bool inside = x >= -w && x < nx + w && y >= -w && y < ny + w;
  const bool near_edge = x < w || x >= nx - w || y < w || y >= ny - w;
  return inside && near_edge;
}

TEST(HaloFrame, EnumeratesTheFrameOnceEach) {
  for (int nx : {1, 2, 3, 5, 8, 17, 64})
    for (int ny : {1, 2, 4, 7, 33})
      for (int w : {0, 1, 2, 3, 4, 8}) {
        const HaloFrame fr{nx, ny, w};
        std::set<std::pair<int, int>> seen;
        for (std::size_t i = 0; i < fr.size(); ++i) {
          int x = 0, y = 0;
          fr.cell(i, x, y);
          EXPECT_TRUE(in_frame(nx, ny, w, x, y))
              << nx << "x" << ny << " w " << w << ": " << x << "," << y;
          EXPECT_TRUE(seen.insert({x, y}).second) << "twice: " << x << "," << y;
        }
        // Every frame cell is numbered: the count is the strips' cells,
        // ghost ring plus the owned ring within w.
        const long long ghosts = (nx + 2LL * w) * (ny + 2LL * w) - 1LL * nx * ny;
        const long long inner_x = nx > 2 * w ? nx - 2 * w : 0,
                        inner_y = ny > 2 * w ? ny - 2 * w : 0;
        const long long owned = 1LL * nx * ny - inner_x * inner_y;
        EXPECT_EQ(static_cast<long long>(fr.size()), w == 0 ? 0 : ghosts + owned)
            << nx << "x" << ny << " w " << w;
        EXPECT_EQ(static_cast<long long>(seen.size()), static_cast<long long>(fr.size()));
      }
}

TEST(HaloFrame, PackUnpackRoundTripsTheFrameAndNothingElse) {
  const TileGeom g = make_single_tile(20, 11, 4, 1.0f);
  Field<std::int64_t> a(g, -1), b(g, 7);
  for (int y = -g.halo; y < g.ny + g.halo; ++y)
    for (int x = -g.halo; x < g.nx + g.halo; ++x) a(x, y) = 1000 * (y + 10) + x + 10;
  const HaloFrame fr{g.nx, g.ny, 3};
  std::vector<std::int64_t> buf(fr.size());
  pack_frame(a, fr, buf.data());
  unpack_frame(buf.data(), fr, b);
  for (int y = -g.halo; y < g.ny + g.halo; ++y)
    for (int x = -g.halo; x < g.nx + g.halo; ++x)
      EXPECT_EQ(b(x, y), in_frame(g.nx, g.ny, 3, x, y) ? a(x, y) : 7) << x << "," << y;
}

}  // namespace
}  // namespace erg::dist
