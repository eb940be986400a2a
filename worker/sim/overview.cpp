// SPDX-License-Identifier: Apache-2.0
// The overview pyramid (sim/overview.h): exact block sums per tile, completed
// by the blocks' owners.
#include "sim/overview.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
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

// A level's blocks of one tile, as the tile's rows stream past (bottom to
// top): the partial sums of the block row being read, the means of the
// blocks the tile owns, and the partial sums of the blocks it shares with
// other tiles (only those: a block wholly inside the tile is final as soon
// as its last row is read). Nothing here grows with the tile's area but the
// means, 12 bytes per block.
struct LevelStream {
  Level lv;
  Rect touched, owned;
  long long cx0 = 0, cx1 = 0, cy0 = 0, cy1 = 0;  // the tile's cells [x0, x1) x [y0, y1)
  std::vector<Sums> row;                         // the block row being read, over touched
  std::unordered_map<long long, Sums> shared;    // blocks straddling a tile edge
  io::OverviewLevel out;

  LevelStream(const dist::Decomposition& d, int level, int ti, int tj)
      : lv{d, level}, touched(lv.touched(ti, tj)), owned(lv.owned(ti, tj)) {
    cx0 = d.x0(ti);
    cx1 = cx0 + d.nx(ti);
    cy0 = d.y0(tj);
    cy1 = cy0 + d.ny(tj);
    row.assign(static_cast<std::size_t>(touched.width()), Sums{});
    out.level = level;
    out.nx = static_cast<int>(lv.blocks_x());
    out.ny = static_cast<int>(lv.blocks_y());
    out.x0 = static_cast<int>(owned.x0);
    out.y0 = static_cast<int>(owned.y0);
    out.bnx = owned.empty() ? 0 : static_cast<int>(owned.width());
    out.bny = owned.empty() ? 0 : static_cast<int>(owned.y1 - owned.y0);
    const std::size_t n = static_cast<std::size_t>(owned.area());
    out.bedrock.resize(n);
    out.sand.resize(n);
    out.vegetation.resize(n);
  }
  long long key(long long bx, long long by) const { return by * lv.blocks_x() + bx; }
  Sums& at_row(long long bx) { return row[static_cast<std::size_t>(bx - touched.x0)]; }
  // Whether some of the block's cells lie in another tile.
  bool straddles(long long bx, long long by) const {
    const long long s = lv.s();
    return bx * s < cx0 || std::min<long long>(lv.d.gnx, (bx + 1) * s) > cx1 || by * s < cy0 ||
           std::min<long long>(lv.d.gny, (by + 1) * s) > cy1;
  }
  void set_mean(long long bx, long long by, const Sums& sums) {
    const std::size_t c =
        static_cast<std::size_t>((by - owned.y0) * owned.width() + (bx - owned.x0));
    const long long cells = lv.cells(bx, by);
    out.bedrock[c] = mean(sums.bedrock, cells, kHeightBits);
    out.sand[c] = mean(sums.sand, cells, kHeightBits);
    out.vegetation[c] = mean(sums.vegetation, cells, kVegetationBits);
  }
  // The block row `by` is read: each block goes to its parent's row (the
  // next level), then is final (a mean) or kept as shared.
  void flush(long long by, LevelStream* parent) {
    for (long long bx = touched.x0; bx < touched.x1; ++bx) {
      Sums& s = at_row(bx);
      if (parent) parent->at_row(bx >> 1) += s;
      if (straddles(bx, by))
        shared[key(bx, by)] = s;
      else
        set_mean(bx, by, s);
      s = Sums{};
    }
  }
};

// The values of the shared blocks in `r`, row-major.
std::vector<Sums> cut(const LevelStream& from, const Rect& r) {
  std::vector<Sums> out;
  out.reserve(static_cast<std::size_t>(r.area()));
  for (long long by = r.y0; by < r.y1; ++by)
    for (long long bx = r.x0; bx < r.x1; ++bx) out.push_back(from.shared.at(from.key(bx, by)));
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

// Completes the shared blocks this rank owns at one level: its own partial
// sums plus those of every other tile that has cells in them (integer sums:
// the order of the messages does not matter), then their means.
void complete(MPI_Comm cart, LevelStream& st, int ti, int tj) {
  const Level& lv = st.lv;
  std::vector<MPI_Request> requests;
  std::vector<std::vector<Sums>> outgoing, incoming;
  std::vector<Rect> incoming_rect;
  std::vector<int> incoming_rank;
  const int tag = 7100 + lv.level;
  int i0, i1, j0, j1;
  // Receive: from the tiles with cells in my blocks (all buffers sized
  // before any receive is posted: none moves afterwards).
  if (!st.owned.empty()) {
    lv.tiles_of(st.owned, i0, i1, j0, j1);
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        if (i == ti && j == tj) continue;
        const Rect r = intersect(lv.touched(i, j), st.owned);
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
  lv.tiles_of(st.touched, i0, i1, j0, j1);
  outgoing.reserve(static_cast<std::size_t>(i1 - i0 + 1) * static_cast<std::size_t>(j1 - j0 + 1));
  requests.reserve(requests.size() + outgoing.capacity());
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      if (i == ti && j == tj) continue;
      const Rect r = intersect(lv.owned(i, j), st.touched);
      if (r.empty()) continue;
      outgoing.push_back(cut(st, r));
      requests.emplace_back();
      MPI_Isend(outgoing.back().data(), bytes_of(r.area()), MPI_BYTE, rank_of(cart, i, j), tag,
                cart, &requests.back());
    }
  MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
  for (std::size_t k = 0; k < incoming.size(); ++k) {
    const Rect& r = incoming_rect[k];
    std::size_t c = 0;
    for (long long by = r.y0; by < r.y1; ++by)
      for (long long bx = r.x0; bx < r.x1; ++bx) st.shared.at(st.key(bx, by)) += incoming[k][c++];
  }
  // The shared blocks I own are now whole.
  const Rect& o = st.owned;
  for (const auto& [k, sums] : st.shared) {
    const long long bx = k % lv.blocks_x(), by = k / lv.blocks_x();
    if (bx >= o.x0 && bx < o.x1 && by >= o.y0 && by < o.y1) st.set_mean(bx, by, sums);
  }
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
                                     const TerrainRows& rows, GroundRange* ground) {
  int ti = 0, tj = 0;
  tile_coords(cart, ti, tj);
  const int levels = io::overview_levels(d.gnx, d.gny);
  // Every level in one pass over the tile's rows, a band at a time: each cell
  // goes into its level-1 block; a block row of level l is read when its last
  // cell row is, and then goes into its parent's row (a block's partial sum
  // is the sum of its four children's). Integer sums: neither the banding nor
  // the order changes a bit.
  std::vector<LevelStream> level;
  level.reserve(static_cast<std::size_t>(levels));
  for (int l = 1; l <= levels; ++l) level.emplace_back(d, l, ti, tj);
  const int x0 = d.x0(ti), y0 = d.y0(tj), nx = d.nx(ti), ny = d.ny(tj);
  const std::size_t band = static_cast<std::size_t>(nx) * kOverviewBandRows;
  std::vector<float> bedrock(band), sand(band), vegetation(band);
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (int b0 = 0; b0 < ny; b0 += kOverviewBandRows) {
    const int b1 = std::min(ny, b0 + kOverviewBandRows);
    rows(0, b0, b1, bedrock.data());
    rows(1, b0, b1, sand.data());
    rows(2, b0, b1, vegetation.data());
    if (ground)
      for (std::size_t c = 0; c < static_cast<std::size_t>(b1 - b0) * nx; ++c) {
        const float h = bedrock[c] + sand[c];
        lo = std::min(lo, h);
        hi = std::max(hi, h);
      }
    if (levels == 0) continue;  // a domain of one cell: no level
    for (int y = b0; y < b1; ++y) {
      for (int x = 0; x < nx; ++x) {
        const std::size_t c = static_cast<std::size_t>(y - b0) * nx + x;
        Sums& s = level.front().at_row((x0 + x) >> 1);
        s.bedrock += fixed(bedrock[c], kHeightBits);
        s.sand += fixed(sand[c], kHeightBits);
        s.vegetation += fixed(vegetation[c], kVegetationBits);
      }
      // Levels whose block row ends with this cell row (a level-(l+1) row
      // ends only where a level-l row does; the tile's last row ends all).
      const long long gy = y0 + y;
      for (int l = 1; l <= levels; ++l) {
        if (((gy + 1) & ((1LL << l) - 1)) != 0 && y != ny - 1) break;
        level[l - 1].flush(gy >> l, l < levels ? &level[l] : nullptr);
      }
    }
  }
  if (ground) {
    MPI_Allreduce(&lo, &ground->min_m, 1, MPI_FLOAT, MPI_MIN, cart);
    MPI_Allreduce(&hi, &ground->max_m, 1, MPI_FLOAT, MPI_MAX, cart);
  }
  io::OverviewPyramid pyramid;
  pyramid.reserve(level.size());
  for (LevelStream& st : level) {
    complete(cart, st, ti, tj);
    pyramid.push_back(std::move(st.out));
    st.shared.clear();
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
