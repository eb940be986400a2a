// SPDX-License-Identifier: Apache-2.0
// decompose() and parse_tiles(): grid choice, tile sizes, errors. No MPI.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "dist/decomposition.h"

namespace erg::dist {
namespace {

// The message of the std::invalid_argument that f throws ("" if none).
template <class F>
std::string error_of(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// Tiles cover the domain exactly, in order, none empty, all but the last of a
// row/column one chunk.
void expect_cover(const Decomposition& d) {
  int x = 0;
  for (int i = 0; i < d.px; ++i) {
    EXPECT_EQ(d.x0(i), x);
    EXPECT_GT(d.nx(i), 0);
    if (i + 1 < d.px) {
      EXPECT_EQ(d.nx(i), d.chunk_x);
    }
    EXPECT_LE(d.nx(i), d.chunk_x);
    EXPECT_GE(d.nx(i), d.min_tile_x());
    x += d.nx(i);
  }
  EXPECT_EQ(x, d.gnx);
  int y = 0;
  for (int j = 0; j < d.py; ++j) {
    EXPECT_EQ(d.y0(j), y);
    EXPECT_GT(d.ny(j), 0);
    if (j + 1 < d.py) {
      EXPECT_EQ(d.ny(j), d.chunk_y);
    }
    EXPECT_LE(d.ny(j), d.chunk_y);
    EXPECT_GE(d.ny(j), d.min_tile_y());
    y += d.ny(j);
  }
  EXPECT_EQ(y, d.gny);
}

TEST(Decompose, OneRankIsTheWholeDomain) {
  const Decomposition d = decompose(37, 23, 1, 8);
  EXPECT_EQ(d.gnx, 37);
  EXPECT_EQ(d.gny, 23);
  EXPECT_EQ(d.px, 1);
  EXPECT_EQ(d.py, 1);
  EXPECT_EQ(d.chunk_x, 37);
  EXPECT_EQ(d.chunk_y, 23);
  expect_cover(d);
}

TEST(Decompose, PicksSquarestTiles) {
  // 4 ranks on a square: 2 x 2, not 4 x 1.
  Decomposition d = decompose(64, 64, 4, 1);
  EXPECT_EQ(d.px, 2);
  EXPECT_EQ(d.py, 2);
  // A wide domain gets more tiles along x.
  d = decompose(400, 100, 4, 1);
  EXPECT_EQ(d.px, 4);
  EXPECT_EQ(d.py, 1);
  d = decompose(100, 400, 4, 1);
  EXPECT_EQ(d.px, 1);
  EXPECT_EQ(d.py, 4);
  // 6 ranks on 300 x 200: 3 x 2 gives 100 x 100 tiles.
  d = decompose(300, 200, 6, 1);
  EXPECT_EQ(d.px, 3);
  EXPECT_EQ(d.py, 2);
  EXPECT_EQ(d.chunk_x, 100);
  EXPECT_EQ(d.chunk_y, 100);
  // 37 x 23: 2 x 2 (19 x 12) beats 4 x 1 (10 x 23) and 1 x 4 (37 x 6).
  d = decompose(37, 23, 4, 1);
  EXPECT_EQ(d.px, 2);
  EXPECT_EQ(d.py, 2);
  expect_cover(d);
  // 3 ranks: 3 x 1 (13 x 23) beats 1 x 3 (37 x 8).
  d = decompose(37, 23, 3, 1);
  EXPECT_EQ(d.px, 3);
  EXPECT_EQ(d.py, 1);
  EXPECT_EQ(d.chunk_x, 13);
  EXPECT_EQ(d.nx(2), 11);
  expect_cover(d);
}

TEST(Decompose, TiesGoToFewerTilesAlongX) {
  // 2 ranks on a square: 2 x 1 and 1 x 2 are equally far from square.
  Decomposition d = decompose(64, 64, 2, 1);
  EXPECT_EQ(d.px, 1);
  EXPECT_EQ(d.py, 2);
  // 8 ranks on a square: 2 x 4 and 4 x 2 tie (32 x 16 vs 16 x 32).
  d = decompose(64, 64, 8, 1);
  EXPECT_EQ(d.px, 2);
  EXPECT_EQ(d.py, 4);
}

TEST(Decompose, UnevenTilesAndEmptyLastTile) {
  // 10 over 4: chunk 3, tiles 3, 3, 3, 1.
  Decomposition d = decompose(10, 1, 4, 1, 4, 1);
  EXPECT_EQ(d.chunk_x, 3);
  EXPECT_EQ(d.nx(0), 3);
  EXPECT_EQ(d.nx(3), 1);
  EXPECT_EQ(d.min_tile_x(), 1);
  expect_cover(d);
  // 10 over 6: chunk 2, five tiles of 2 and an empty sixth: rejected.
  const std::string e = error_of([] { decompose(10, 1, 6, 1, 6, 1); });
  EXPECT_TRUE(contains(e, "empty")) << e;
  // Automatic choice skips grids with an empty tile: 6 ranks on 10 x 10 can
  // be 2 x 3 (5 x 4 tiles, last row 2) but never 6 x 1 or 1 x 6.
  d = decompose(10, 10, 6, 1);
  EXPECT_EQ(d.px * d.py, 6);
  EXPECT_TRUE((d.px == 2 && d.py == 3) || (d.px == 3 && d.py == 2));
  expect_cover(d);
}

TEST(Decompose, MinimumTileRulesOutGrids) {
  // 64 x 64 on 4 ranks: 2 x 2 (32 x 32) fits a minimum of 20...
  Decomposition d = decompose(64, 64, 4, 20);
  EXPECT_EQ(d.px, 2);
  EXPECT_EQ(d.py, 2);
  // ...but nothing fits 40 (4 x 1 and 1 x 4 have 16-cell sides).
  EXPECT_THROW(decompose(64, 64, 4, 40), std::invalid_argument);
  // 8 x 21 on 4 ranks: the squarest, 1 x 4 (8 x 6 chunks), leaves a last
  // tile 3 rows high; with a minimum of 4 the less square 2 x 2 (4 x 11) is
  // taken instead.
  d = decompose(8, 21, 4, 1);
  EXPECT_EQ(d.px, 1);
  EXPECT_EQ(d.py, 4);
  EXPECT_EQ(d.min_tile_y(), 3);
  d = decompose(8, 21, 4, 4);
  EXPECT_EQ(d.px, 2);
  EXPECT_EQ(d.py, 2);
  expect_cover(d);
  // 120 x 60 on 4 ranks with a minimum of 30: 2 x 2 (60 x 30) and 4 x 1
  // (30 x 60) are equally square: fewer tiles along x wins.
  d = decompose(120, 60, 4, 30);
  EXPECT_EQ(d.px, 2);
  EXPECT_EQ(d.py, 2);
  // 90 x 90 on 9 ranks: 3 x 3 (30 x 30) does not fit 40, nor 9 x 1.
  EXPECT_THROW(decompose(90, 90, 9, 40), std::invalid_argument);
  // The last, smaller tile counts: 100 over 3 is 34, 34, 32.
  EXPECT_THROW(decompose(100, 100, 3, 33, 3, 1), std::invalid_argument);
  d = decompose(100, 100, 3, 32, 3, 1);
  EXPECT_EQ(d.min_tile_x(), 32);
}

TEST(Decompose, ErrorNamesDomainRanksAndMinimum) {
  const std::string e = error_of([] { decompose(64, 48, 6, 40); });
  EXPECT_TRUE(contains(e, "64 x 48")) << e;
  EXPECT_TRUE(contains(e, "6 tiles")) << e;
  EXPECT_TRUE(contains(e, "40 x 40")) << e;
  EXPECT_TRUE(contains(e, "fewer ranks")) << e;
  // The squarest candidate's tile size is named: 3 x 2 of 64 x 48 gives
  // 22 x 24 cells (the last column 20 wide).
  EXPECT_TRUE(contains(e, "3 x 2")) << e;
}

TEST(Decompose, UserGrid) {
  Decomposition d = decompose(37, 23, 4, 1, 4, 1);
  EXPECT_EQ(d.px, 4);
  EXPECT_EQ(d.py, 1);
  EXPECT_EQ(d.chunk_x, 10);
  EXPECT_EQ(d.nx(3), 7);
  expect_cover(d);
  d = decompose(37, 23, 4, 1, 1, 4);
  EXPECT_EQ(d.chunk_y, 6);
  EXPECT_EQ(d.ny(3), 5);
  expect_cover(d);
  // The product must be the rank count.
  std::string e = error_of([] { decompose(37, 23, 4, 1, 3, 2); });
  EXPECT_TRUE(contains(e, "3 x 2")) << e;
  EXPECT_TRUE(contains(e, "4 ranks")) << e;
  // Too small for the halo.
  e = error_of([] { decompose(64, 48, 6, 20, 6, 1); });
  EXPECT_TRUE(contains(e, "64 x 48")) << e;
  EXPECT_TRUE(contains(e, "6 x 1")) << e;
  EXPECT_TRUE(contains(e, "20 x 20")) << e;
  EXPECT_TRUE(contains(e, "6 ranks")) << e;
  EXPECT_TRUE(contains(e, "11 x 48") || contains(e, "9 x 48")) << e;
  // Only one of px, py given, or negative.
  EXPECT_THROW(decompose(37, 23, 4, 1, 4, 0), std::invalid_argument);
  EXPECT_THROW(decompose(37, 23, 4, 1, 0, 4), std::invalid_argument);
  EXPECT_THROW(decompose(37, 23, 4, 1, -2, -2), std::invalid_argument);
}

TEST(Decompose, BadArguments) {
  EXPECT_THROW(decompose(0, 10, 1, 1), std::invalid_argument);
  EXPECT_THROW(decompose(10, -1, 1, 1), std::invalid_argument);
  EXPECT_THROW(decompose(10, 10, 0, 1), std::invalid_argument);
  EXPECT_THROW(decompose(10, 10, 1, -1), std::invalid_argument);
  // More ranks than cells.
  EXPECT_THROW(decompose(2, 2, 5, 1), std::invalid_argument);
  // min_tile 0 still forbids empty tiles.
  EXPECT_THROW(decompose(10, 1, 6, 0, 6, 1), std::invalid_argument);
  EXPECT_NO_THROW(decompose(10, 1, 4, 0, 4, 1));
}

TEST(Decompose, EveryRankCountCoversTheDomain) {
  for (int ranks = 1; ranks <= 24; ++ranks)
    for (const int gnx : {31, 64, 97})
      for (const int gny : {17, 64, 120}) {
        Decomposition d;
        try {
          d = decompose(gnx, gny, ranks, 4);
        } catch (const std::invalid_argument&) {
          continue;
        }
        EXPECT_EQ(d.px * d.py, ranks);
        EXPECT_GE(d.min_tile_x(), 4);
        EXPECT_GE(d.min_tile_y(), 4);
        expect_cover(d);
      }
}

TEST(ParseTiles, Valid) {
  int px = 0, py = 0;
  parse_tiles("3x2", px, py);
  EXPECT_EQ(px, 3);
  EXPECT_EQ(py, 2);
  parse_tiles("1x16", px, py);
  EXPECT_EQ(px, 1);
  EXPECT_EQ(py, 16);
  parse_tiles("12X5", px, py);
  EXPECT_EQ(px, 12);
  EXPECT_EQ(py, 5);
}

TEST(ParseTiles, InvalidNamesTheText) {
  for (const std::string text : {"", "x", "3", "3x", "x2", "3x2x1", "0x2", "3x0", "-1x2", "3 x 2",
                                 " 3x2", "3x2 ", "axb", "3y2", "3*2", "99999999999x1", "+3x2"}) {
    int px = 7, py = 7;
    const std::string e = error_of([&] { parse_tiles(text, px, py); });
    EXPECT_TRUE(contains(e, "\"" + text + "\"")) << "text \"" << text << "\": " << e;
    EXPECT_EQ(px, 7);
    EXPECT_EQ(py, 7);
  }
}

}  // namespace
}  // namespace erg::dist
