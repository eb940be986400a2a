// SPDX-License-Identifier: Apache-2.0
// The overview pyramid (sim/overview.h): exact block sums per tile, completed
// by the blocks' owners.
#include "sim/overview.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/units.h"

namespace erg {
namespace {

// A block's exact sums: bedrock and sand in 2^-32 m, vegetation in 2^-64.
struct Sums {
  total_t bedrock = 0, sand = 0, vegetation = 0;
  Sums& operator+=(const Sums& o) {
    bedrock += o.bedrock;
    sand += o.sand;
    vegetation += o.vegetation;
    return *this;
  }
};
constexpr int kHeightBits = 32, kVegetationBits = 64;

// A float32 of a snapshot layer as a whole number of 2^-bits (NaN or
// infinite: 0, as the preview draws them). Exact for heights: a float32
// metres value of the model is float(u) * 2^-32 with u an integer.
total_t fixed(float v, int bits) {
  if (!std::isfinite(v)) return 0;
  return static_cast<total_t>(std::ldexp(static_cast<double>(v), bits));
}
float mean(total_t sum, long long cells, int bits) {
  return static_cast<float>(
      std::ldexp(static_cast<double>(sum) / static_cast<double>(cells), -bits));
}

// A rectangle of blocks [x0, x1) x [y0, y1).
struct Rect {
  long long x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  long long width() const { return x1 - x0; }
  long long area() const { return empty() ? 0 : (x1 - x0) * (y1 - y0); }
};
Rect intersect(const Rect& a, const Rect& b) {
  return {std::max(a.x0, b.x0), std::min(a.x1, b.x1), std::max(a.y0, b.y0), std::min(a.y1, b.y1)};
}

// The geometry of one level over the tiling.
struct Level {
  const dist::Decomposition& d;
  int level;
  long long s() const { return 1LL << level; }
  long long blocks_x() const { return (d.gnx + s() - 1) >> level; }
  long long blocks_y() const { return (d.gny + s() - 1) >> level; }
  // The blocks tile (i, j) has cells of.
  Rect touched(int i, int j) const {
    return {d.x0(i) >> level, ((d.x0(i) + d.nx(i) - 1) >> level) + 1, d.y0(j) >> level,
            ((d.y0(j) + d.ny(j) - 1) >> level) + 1};
  }
  // The blocks whose first cell tile (i, j) holds.
  Rect owned(int i, int j) const {
    const auto up = [&](long long c) { return (c + s() - 1) >> level; };
    return {up(d.x0(i)), up(d.x0(i) + d.nx(i)), up(d.y0(j)), up(d.y0(j) + d.ny(j))};
  }
  // The tiles holding cells of the blocks r (inclusive ranges).
  void tiles_of(const Rect& r, int& i0, int& i1, int& j0, int& j1) const {
    const auto tx = [&](long long c) {
      return static_cast<int>(std::min<long long>(d.px - 1, c / d.chunk_x));
    };
    const auto ty = [&](long long c) {
      return static_cast<int>(std::min<long long>(d.py - 1, c / d.chunk_y));
    };
    i0 = tx(r.x0 * s());
    i1 = tx(std::min<long long>(d.gnx, r.x1 * s()) - 1);
    j0 = ty(r.y0 * s());
    j1 = ty(std::min<long long>(d.gny, r.y1 * s()) - 1);
  }
  long long cells(long long bx, long long by) const {
    const long long w = std::min<long long>(d.gnx, (bx + 1) * s()) - bx * s();
    const long long h = std::min<long long>(d.gny, (by + 1) * s()) - by * s();
    return w * h;
  }
};

// Partial sums over the rectangle `r` of blocks (row-major).
struct Partial {
  Rect r;
  std::vector<Sums> v;
  Sums& at(long long bx, long long by) {
    return v[static_cast<std::size_t>((by - r.y0) * r.width() + (bx - r.x0))];
  }
};

// The values of `from` in `r` (inside from.r), row-major.
std::vector<Sums> cut(Partial& from, const Rect& r) {
  std::vector<Sums> out;
  out.reserve(static_cast<std::size_t>(r.area()));
  for (long long by = r.y0; by < r.y1; ++by)
    for (long long bx = r.x0; bx < r.x1; ++bx) out.push_back(from.at(bx, by));
  return out;
}

int rank_of(MPI_Comm cart, int i, int j) {
  int coords[2] = {i, j}, r = 0;
  MPI_Cart_rank(cart, coords, &r);
  return r;
}

int bytes_of(long long blocks) {
  const long long b = blocks * static_cast<long long>(sizeof(Sums));
  if (b > 2147483647LL) throw std::runtime_error("overview: a message of more than 2 GiB");
  return static_cast<int>(b);
}

// Completes the blocks this rank owns at one level: its own partial sums
// plus those of every other tile that has cells in them (integer sums: the
// order of the messages does not matter).
Partial complete(MPI_Comm cart, const Level& lv, int ti, int tj, Partial& mine) {
  Partial own{lv.owned(ti, tj), {}};
  own.v = own.r.empty() ? std::vector<Sums>{} : cut(mine, own.r);
  std::vector<MPI_Request> requests;
  std::vector<std::vector<Sums>> outgoing, incoming;
  std::vector<Rect> incoming_rect;
  std::vector<int> incoming_rank;
  const int tag = 7100 + lv.level;
  int i0, i1, j0, j1;
  // Receive: from the tiles with cells in my blocks (all buffers sized
  // before any receive is posted: none moves afterwards).
  if (!own.r.empty()) {
    lv.tiles_of(own.r, i0, i1, j0, j1);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        if (i == ti && j == tj) continue;
        const Rect r = intersect(lv.touched(i, j), own.r);
        if (r.empty()) continue;
        incoming_rect.push_back(r);
        incoming_rank.push_back(rank_of(cart, i, j));
        incoming.emplace_back(static_cast<std::size_t>(r.area()));
      }
  }
  for (std::size_t k = 0; k < incoming.size(); ++k) {
    requests.emplace_back();
    MPI_Irecv(incoming[k].data(), bytes_of(incoming_rect[k].area()), MPI_BYTE, incoming_rank[k],
              tag, cart, &requests.back());
  }
  // Send: my cells in the blocks other tiles own.
  lv.tiles_of(mine.r, i0, i1, j0, j1);
  outgoing.reserve(static_cast<std::size_t>(i1 - i0 + 1) * static_cast<std::size_t>(j1 - j0 + 1));
  requests.reserve(requests.size() + outgoing.capacity());
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      if (i == ti && j == tj) continue;
      const Rect r = intersect(lv.owned(i, j), mine.r);
      if (r.empty()) continue;
      outgoing.push_back(cut(mine, r));
      requests.emplace_back();
      MPI_Isend(outgoing.back().data(), bytes_of(r.area()), MPI_BYTE, rank_of(cart, i, j), tag,
                cart, &requests.back());
    }
  MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
  for (std::size_t k = 0; k < incoming.size(); ++k) {
    const Rect& r = incoming_rect[k];
    std::size_t c = 0;
    for (long long by = r.y0; by < r.y1; ++by)
      for (long long bx = r.x0; bx < r.x1; ++bx) own.at(bx, by) += incoming[k][c++];
  }
  return own;
}

io::OverviewLevel means(const Level& lv, const Partial& own) {
  io::OverviewLevel out;
  out.level = lv.level;
  out.nx = static_cast<int>(lv.blocks_x());
  out.ny = static_cast<int>(lv.blocks_y());
  out.x0 = static_cast<int>(own.r.x0);
  out.y0 = static_cast<int>(own.r.y0);
  out.bnx = own.r.empty() ? 0 : static_cast<int>(own.r.width());
  out.bny = own.r.empty() ? 0 : static_cast<int>(own.r.y1 - own.r.y0);
  const std::size_t n = static_cast<std::size_t>(own.r.area());
  out.bedrock.resize(n);
  out.sand.resize(n);
  out.vegetation.resize(n);
  std::size_t c = 0;
  for (long long by = own.r.y0; by < own.r.y1 && n; ++by)
    for (long long bx = own.r.x0; bx < own.r.x1; ++bx, ++c) {
      const long long cells = lv.cells(bx, by);
      const Sums& s = own.v[c];
      out.bedrock[c] = mean(s.bedrock, cells, kHeightBits);
      out.sand[c] = mean(s.sand, cells, kHeightBits);
      out.vegetation[c] = mean(s.vegetation, cells, kVegetationBits);
    }
  return out;
}

void tile_coords(MPI_Comm cart, int& ti, int& tj) {
  int rank = 0, coords[2] = {0, 0};
  MPI_Comm_rank(cart, &rank);
  MPI_Cart_coords(cart, rank, 2, coords);
  ti = coords[0];
  tj = coords[1];
}

}  // namespace

io::OverviewPyramid overview_pyramid(MPI_Comm cart, const dist::Decomposition& d,
                                     const TerrainRows& rows) {
  int ti = 0, tj = 0;
  tile_coords(cart, ti, tj);
  const int levels = io::overview_levels(d.gnx, d.gny);
  io::OverviewPyramid pyramid;
  if (levels == 0) return pyramid;
  // Level 1 from the cells, each further level from the one before: a
  // block's partial sum is the sum of its four children's.
  Partial prev;
  const int x0 = d.x0(ti), y0 = d.y0(tj), nx = d.nx(ti), ny = d.ny(tj);
  for (int l = 1; l <= levels; ++l) {
    const Level lv{d, l};
    Partial cur{lv.touched(ti, tj), {}};
    cur.v.assign(static_cast<std::size_t>(cur.r.area()), Sums{});
    if (l == 1) {
      // A band of rows at a time (integer sums: the banding changes no bit).
      const std::size_t band = static_cast<std::size_t>(nx) * kOverviewBandRows;
      std::vector<float> bedrock(band), sand(band), vegetation(band);
      for (int b0 = 0; b0 < ny; b0 += kOverviewBandRows) {
        const int b1 = std::min(ny, b0 + kOverviewBandRows);
        rows(0, b0, b1, bedrock.data());
        rows(1, b0, b1, sand.data());
        rows(2, b0, b1, vegetation.data());
        for (int y = b0; y < b1; ++y)
          for (int x = 0; x < nx; ++x) {
            const std::size_t c = static_cast<std::size_t>(y - b0) * nx + x;
            Sums& s = cur.at((x0 + x) >> 1, (y0 + y) >> 1);
            s.bedrock += fixed(bedrock[c], kHeightBits);
            s.sand += fixed(sand[c], kHeightBits);
            s.vegetation += fixed(vegetation[c], kVegetationBits);
          }
      }
    } else {
      for (long long by = prev.r.y0; by < prev.r.y1; ++by)
        for (long long bx = prev.r.x0; bx < prev.r.x1; ++bx)
          cur.at(bx >> 1, by >> 1) += prev.at(bx, by);
    }
    pyramid.push_back(means(lv, complete(cart, lv, ti, tj, cur)));
    prev = std::move(cur);
  }
  return pyramid;
}

io::OverviewLevel gather_overview_level(MPI_Comm cart, const dist::Decomposition& d,
                                        const io::OverviewPyramid& pyramid, int level,
                                        const TerrainRows& rows) {
  int rank = 0, size = 1, ti = 0, tj = 0;
  MPI_Comm_rank(cart, &rank);
  MPI_Comm_size(cart, &size);
  tile_coords(cart, ti, tj);
  // This rank's blocks, the three layers one after the other.
  std::vector<float> mine;
  const Level lv{d, level};
  if (level == 0) {
    const std::size_t n = static_cast<std::size_t>(d.nx(ti)) * d.ny(tj);
    mine.resize(3 * n);
    if (n > 0)
      for (int layer = 0; layer < 3; ++layer) rows(layer, 0, d.ny(tj), mine.data() + layer * n);
  } else {
    const io::OverviewLevel& l = pyramid.at(static_cast<std::size_t>(level - 1));
    mine = l.bedrock;
    mine.insert(mine.end(), l.sand.begin(), l.sand.end());
    mine.insert(mine.end(), l.vegetation.begin(), l.vegetation.end());
  }
  io::OverviewLevel whole;
  whole.level = level;
  whole.nx = whole.bnx = static_cast<int>(lv.blocks_x());
  whole.ny = whole.bny = static_cast<int>(lv.blocks_y());
  std::vector<int> counts, displs;
  std::vector<Rect> rects;
  std::vector<float> all;
  if (rank == 0) {
    counts.resize(static_cast<std::size_t>(size));
    displs.resize(static_cast<std::size_t>(size));
    rects.resize(static_cast<std::size_t>(size));
    long long total = 0;
    for (int r = 0; r < size; ++r) {
      int coords[2];
      MPI_Cart_coords(cart, r, 2, coords);
      rects[r] = level == 0 ? Rect{d.x0(coords[0]), d.x0(coords[0]) + d.nx(coords[0]),
                                   d.y0(coords[1]), d.y0(coords[1]) + d.ny(coords[1])}
                            : lv.owned(coords[0], coords[1]);
      counts[r] = static_cast<int>(3 * rects[r].area());
      displs[r] = static_cast<int>(total);
      total += counts[r];
    }
    all.resize(static_cast<std::size_t>(total));
  }
  MPI_Gatherv(mine.data(), static_cast<int>(mine.size()), MPI_FLOAT, all.data(), counts.data(),
              displs.data(), MPI_FLOAT, 0, cart);
  if (rank != 0) return {};
  const std::size_t n = static_cast<std::size_t>(whole.nx) * whole.ny;
  whole.bedrock.resize(n);
  whole.sand.resize(n);
  whole.vegetation.resize(n);
  for (int r = 0; r < size; ++r) {
    const Rect& b = rects[r];
    const long long area = b.area();
    const float* p = all.data() + displs[r];
    long long c = 0;
    for (long long by = b.y0; by < b.y1 && area; ++by)
      for (long long bx = b.x0; bx < b.x1; ++bx, ++c) {
        const std::size_t at = static_cast<std::size_t>(by * whole.nx + bx);
        whole.bedrock[at] = p[c];
        whole.sand[at] = p[area + c];
        whole.vegetation[at] = p[2 * area + c];
      }
  }
  return whole;
}

}  // namespace erg
