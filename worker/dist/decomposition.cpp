// SPDX-License-Identifier: Apache-2.0
#include "dist/decomposition.h"

#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace erg::dist {

namespace {

// Tiles of ceil(n / p) cells, rounded up to a multiple of the alignment.
Decomposition make(int gnx, int gny, int px, int py, int ax, int ay) {
  Decomposition d;
  d.gnx = gnx;
  d.gny = gny;
  d.px = px;
  d.py = py;
  d.chunk_x = ((gnx + px - 1) / px + ax - 1) / ax * ax;
  d.chunk_y = ((gny + py - 1) / py + ay - 1) / ay * ay;
  return d;
}

// Every tile has at least `min_tile` cells (and at least one) along each axis.
bool fits(const Decomposition& d, int min_tile) {
  const int need = min_tile > 1 ? min_tile : 1;
  return d.min_tile_x() >= need && d.min_tile_y() >= need;
}

// a is closer to square than b: chunk ratios compared exactly as
// max/min, i.e. |log(chunk_x / chunk_y)|, by cross-multiplication.
bool squarer(const Decomposition& a, const Decomposition& b) {
  const auto big = [](const Decomposition& d) {
    return static_cast<std::int64_t>(d.chunk_x > d.chunk_y ? d.chunk_x : d.chunk_y);
  };
  const auto small = [](const Decomposition& d) {
    return static_cast<std::int64_t>(d.chunk_x < d.chunk_y ? d.chunk_x : d.chunk_y);
  };
  return big(a) * small(b) < big(b) * small(a);
}

std::string cells(int x, int y) {
  return std::to_string(x) + " x " + std::to_string(y);
}

std::string why(const Decomposition& d) {
  if (d.min_tile_x() <= 0 || d.min_tile_y() <= 0)
    return "the last tile along " + std::string(d.min_tile_x() <= 0 ? "x" : "y") +
           " would be empty (tiles are " + cells(d.chunk_x, d.chunk_y) + " cells)";
  return "the smallest tile would be " + cells(d.min_tile_x(), d.min_tile_y()) + " cells";
}

}  // namespace

Decomposition decompose(int gnx, int gny, int ranks, int min_tile, int px, int py, int align_x,
                        int align_y) {
  if (align_x < 1 || align_y < 1) throw std::invalid_argument("tile alignment must be at least 1");
  if (gnx <= 0 || gny <= 0)
    throw std::invalid_argument("cannot decompose a domain of " + cells(gnx, gny) +
                                " cells: both sides must be positive");
  if (ranks <= 0)
    throw std::invalid_argument("cannot decompose " + cells(gnx, gny) + " cells into " +
                                std::to_string(ranks) + " tiles: need at least one rank");
  if (min_tile < 0)
    throw std::invalid_argument("minimum tile size " + std::to_string(min_tile) + " is negative");
  if (px < 0 || py < 0 || (px > 0) != (py > 0))
    throw std::invalid_argument("invalid tile grid " + std::to_string(px) + " x " +
                                std::to_string(py) +
                                ": give both tile counts (positive), or neither");
  const std::string need = cells(min_tile, min_tile);

  if (px > 0) {  // the user's grid
    if (static_cast<std::int64_t>(px) * py != ranks)
      throw std::invalid_argument("tile grid " + std::to_string(px) + " x " + std::to_string(py) +
                                  " has " + std::to_string(static_cast<std::int64_t>(px) * py) +
                                  " tiles but there are " + std::to_string(ranks) +
                                  " ranks: the product must equal the rank count");
    const Decomposition d = make(gnx, gny, px, py, align_x, align_y);
    if (!fits(d, min_tile))
      throw std::invalid_argument("cannot split " + cells(gnx, gny) + " cells into " +
                                  std::to_string(px) + " x " + std::to_string(py) + " tiles (" +
                                  std::to_string(ranks) + " ranks) of at least " + need +
                                  " cells (the widest halo): " + why(d) +
                                  "; use fewer ranks, another tile grid or a larger domain");
    return d;
  }

  // Every factorisation px * py == ranks that fits; the squarest tiles win,
  // ties go to fewer tiles along x (px ascending, strict improvement only).
  bool found = false;
  Decomposition best;
  bool any = false;
  Decomposition squarest;  // the squarest of all, fitting or not (for the message)
  for (int i = 1; i <= ranks; ++i) {
    if (ranks % i != 0) continue;
    const Decomposition d = make(gnx, gny, i, ranks / i, align_x, align_y);
    if (!any || squarer(d, squarest)) squarest = d;
    any = true;
    if (!fits(d, min_tile)) continue;
    if (!found || squarer(d, best)) best = d;
    found = true;
  }
  if (!found)
    throw std::invalid_argument(
        "cannot split " + cells(gnx, gny) + " cells into " + std::to_string(ranks) +
        " tiles of at least " + need + " cells (the widest halo): the squarest grid, " +
        std::to_string(squarest.px) + " x " + std::to_string(squarest.py) + ", " +
        (squarest.min_tile_x() <= 0 || squarest.min_tile_y() <= 0
             ? "would leave a tile empty"
             : "has tiles as small as " + cells(squarest.min_tile_x(), squarest.min_tile_y())) +
        " cells; use fewer ranks or a larger domain");
  return best;
}

void parse_tiles(const std::string& text, int& px, int& py) {
  const auto bad = [&text]() {
    return std::invalid_argument("invalid tile grid \"" + text +
                                 "\": expected PXxPY with positive integers, e.g. 3x2");
  };
  const auto number = [&](std::size_t begin, std::size_t end) {
    if (begin >= end) throw bad();
    long long v = 0;
    for (std::size_t k = begin; k < end; ++k) {
      const char c = text[k];
      if (c < '0' || c > '9') throw bad();
      v = v * 10 + (c - '0');
      if (v > std::numeric_limits<int>::max()) throw bad();
    }
    if (v <= 0) throw bad();
    return static_cast<int>(v);
  };
  const std::size_t sep = text.find_first_of("xX");
  if (sep == std::string::npos) throw bad();
  const int x = number(0, sep);
  const int y = number(sep + 1, text.size());
  px = x;
  py = y;
}

}  // namespace erg::dist
