// SPDX-License-Identifier: Apache-2.0
// HaloExchanger under mpirun (1 to 4 ranks): every tile's ghosts after fill()
// and owned cells after sum() must equal what the single-process periodic
// wrap gives on the whole domain, here computed from the global picture on
// every rank.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "dist/decomposition.h"
#include "dist/halo.h"
#include "dist/halo_frame.h"
#include "dist/halo_path.h"
#include "dist/mpi_exchange.h"

#if __has_include(<mpi-ext.h>)
#include <mpi-ext.h>
#endif

namespace erg::dist {
namespace {

int world_size() {
  int n = 0;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

// Every test ends by agreeing on failure: a test that failed only on another
// rank fails on this one too (so rank 0's report is the verdict).
class Dist : public ::testing::Test {
 protected:
  void TearDown() override {
    int mine = HasFailure() ? 1 : 0, any = 0;
    MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (any && !mine) ADD_FAILURE() << "failed on another rank (see its [rank N] lines)";
  }
};

// ---- the tile of this rank --------------------------------------------------

struct Config {
  const char* name;
  int gnx, gny;
  int px, py;  // 0, 0: decompose() chooses; -1: the number of ranks
  int halo;
  int ranks;  // the only rank count it runs with (0: any)
};

std::string config_name(const ::testing::TestParamInfo<Config>& info) {
  return info.param.name;
}

// A periodic Cartesian communicator over the decomposition and this rank's
// tile.
class TileSetup {
 public:
  TileSetup(int gnx, int gny, int px, int py, int halo) {
    const int n = world_size();
    if (px < 0) px = n;
    if (py < 0) py = n;
    d = decompose(gnx, gny, n, 1, px, py);
    int dims[2] = {d.px, d.py}, periods[2] = {1, 1};
    MPI_Cart_create(MPI_COMM_WORLD, 2, dims, periods, 0, &cart);
    int rank = 0, coords[2] = {0, 0};
    MPI_Comm_rank(cart, &rank);
    MPI_Cart_coords(cart, rank, 2, coords);
    i = coords[0];
    j = coords[1];
    g = tile(i, j, halo);
  }
  explicit TileSetup(const Config& c) : TileSetup(c.gnx, c.gny, c.px, c.py, c.halo) {}
  ~TileSetup() { MPI_Comm_free(&cart); }
  TileSetup(const TileSetup&) = delete;
  TileSetup& operator=(const TileSetup&) = delete;

  TileGeom tile(int ti, int tj, int halo) const {
    TileGeom t;
    t.nx = d.nx(ti);
    t.ny = d.ny(tj);
    t.halo = halo;
    t.pitch = padded_pitch(t.nx, halo);
    t.x0 = d.x0(ti);
    t.y0 = d.y0(tj);
    t.gnx = d.gnx;
    t.gny = d.gny;
    return t;
  }
  // The widest exchange every rank can serve.
  int max_width() const { return std::min({g.halo, d.min_tile_x(), d.min_tile_y()}); }

  Decomposition d;
  MPI_Comm cart = MPI_COMM_NULL;
  int i = 0, j = 0;
  TileGeom g;
};

// ---- values -----------------------------------------------------------------

std::uint64_t mix(std::uint64_t z) {  // splitmix64 finaliser
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Distinct per global cell (idx < 2^20), exact only as the type itself:
// int64 near +-2^62 (not representable in double), floats off the integers.
template <class T>
T cell_value(std::uint64_t idx);
template <>
std::int64_t cell_value(std::uint64_t idx) {
  const std::int64_t m = (std::int64_t{1} << 62) + static_cast<std::int64_t>(idx) * 3 + 1;
  return idx % 2 ? -m : m;
}
template <>
float cell_value(std::uint64_t idx) {
  return (idx % 2 ? -1.0f : 1.0f) * (static_cast<float>(idx) + 0.375f);
}
template <>
double cell_value(std::uint64_t idx) {
  return (idx % 2 ? -1.0 : 1.0) * (static_cast<double>(idx) / 3.0 + 1e6);
}

// Summands whose sums (at most 9 per cell) are exact in T: int64 up to
// 2^59 + 2^20 in magnitude, floats integers and halves below 2^15.
template <class T>
T summand(std::uint64_t key);
template <>
std::int64_t summand(std::uint64_t key) {
  const std::uint64_t h = mix(key);
  const std::int64_t m = (std::int64_t{1} << 59) + static_cast<std::int64_t>(h >> 44);
  return h & 1 ? -m : m;
}
template <>
float summand(std::uint64_t key) {
  const std::uint64_t h = mix(key);
  return static_cast<float>(static_cast<int>(h >> 50) - 8192) + (h & 1 ? 0.5f : 0.0f);
}
template <>
double summand(std::uint64_t key) {
  const std::uint64_t h = mix(key);
  return static_cast<double>(static_cast<std::int64_t>(h >> 34) - (std::int64_t{1} << 29)) +
         (h & 1 ? 0.25 : 0.0);
}

// Keys of the summands: owned cells by global index, ghosts by tile and
// local position (every tile's ghost of a cell is a different summand).
std::uint64_t owned_key(std::uint64_t idx) {
  return idx * 2 + 1;
}
std::uint64_t ghost_key(int ti, int tj, int x, int y) {
  return ((((static_cast<std::uint64_t>(ti) * 64 + tj) * 1024 + (x + 512)) * 1024 + (y + 512)) * 2);
}

// Never one of the values above.
template <class T>
T marker() {
  return static_cast<T>(7);
}

template <class T>
bool same(T a, T b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

template <class T>
std::string show(T v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

// Counts mismatches and keeps the first few for the report.
class Mismatches {
 public:
  template <class T>
  void check(const char* what, int x, int y, T got, T want) {
    if (same(got, want)) return;
    if (++count_ <= 5)
      text_ += std::string(what) + " (" + std::to_string(x) + ", " + std::to_string(y) + "): got " +
               show(got) + ", want " + show(want) + "\n";
  }
  long count() const { return count_; }
  const std::string& text() const { return text_; }

 private:
  long count_ = 0;
  std::string text_;
};

// The whole stored tile, padding included: x from -halo to pitch - halo.
template <class F>
void for_storage(const TileGeom& g, F f) {
  for (int y = -g.halo; y < g.ny + g.halo; ++y)
    for (int x = -g.halo; x < g.pitch - g.halo; ++x) f(x, y);
}

bool owned(const TileGeom& g, int x, int y) {
  return x >= 0 && x < g.nx && y >= 0 && y < g.ny;
}
bool in_ring(const TileGeom& g, int w, int x, int y) {
  return x >= -w && x < g.nx + w && y >= -w && y < g.ny + w;
}

// ---- fill ---------------------------------------------------------------------

// Owned cells from the global field, every other stored cell the marker.
template <class T>
Field<T> fill_input(const TileGeom& g) {
  Field<T> f(g, marker<T>());
  for (int y = 0; y < g.ny; ++y)
    for (int x = 0; x < g.nx; ++x) f(x, y) = cell_value<T>(g.global_index(x, y));
  return f;
}

// Ghosts within w hold the wrapped global cell; everything else unchanged.
template <class T>
void expect_filled(const Field<T>& f, int w, const std::string& where) {
  const TileGeom& g = f.geom();
  Mismatches m;
  for_storage(g, [&](int x, int y) {
    const bool ghost = !owned(g, x, y) && in_ring(g, w, x, y);
    const T want = owned(g, x, y) || ghost ? cell_value<T>(g.global_index(x, y)) : marker<T>();
    m.check(ghost ? "ghost" : owned(g, x, y) ? "owned" : "untouched", x, y, f(x, y), want);
  });
  EXPECT_EQ(m.count(), 0) << where << ", w " << w << ":\n" << m.text();
}

template <class T>
void check_fill(HaloExchanger& hx, const TileSetup& s, bool split) {
  for (int w = 0; w <= std::min(8, s.max_width()); ++w) {
    Field<T> f = fill_input<T>(s.g);
    if (split) {
      hx.begin_fill(f, w);
      // Interior work that does not read the ghosts may run here.
      Field<T> other = fill_input<T>(s.g);
      other(0, 0) = marker<T>();
      hx.finish_fill(f, w);
    } else {
      hx.fill(f, w);
    }
    expect_filled(f, w,
                  std::string(split ? "begin/finish_fill" : "fill") + " tile (" +
                      std::to_string(s.i) + ", " + std::to_string(s.j) + ")");
  }
}

// ---- sum ----------------------------------------------------------------------

// Owned cells and ghosts within w: distinct summands; the ghosts beyond w
// and the padding: the marker (sum() must leave them alone).
template <class T>
Field<T> sum_input(const TileSetup& s, int ti, int tj, int w) {
  const TileGeom g = s.tile(ti, tj, s.g.halo);
  Field<T> f(g, marker<T>());
  for_storage(g, [&](int x, int y) {
    if (owned(g, x, y))
      f(x, y) = summand<T>(owned_key(g.global_index(x, y)));
    else if (in_ring(g, w, x, y))
      f(x, y) = summand<T>(ghost_key(ti, tj, x, y));
  });
  return f;
}

// The whole domain after the single-process fold: each owned cell plus
// every ghost of every tile that wraps onto it.
template <class T>
std::vector<T> folded(const TileSetup& s, int w) {
  const Decomposition& d = s.d;
  std::vector<T> all(static_cast<std::size_t>(d.gnx) * d.gny);
  for (int gy = 0; gy < d.gny; ++gy)
    for (int gx = 0; gx < d.gnx; ++gx) {
      const std::uint64_t idx = static_cast<std::uint64_t>(gy) * d.gnx + gx;
      all[idx] = summand<T>(owned_key(idx));
    }
  for (int tj = 0; tj < d.py; ++tj)
    for (int ti = 0; ti < d.px; ++ti) {
      const TileGeom g = s.tile(ti, tj, s.g.halo);
      for (int y = -w; y < g.ny + w; ++y)
        for (int x = -w; x < g.nx + w; ++x)
          if (!owned(g, x, y)) all[g.global_index(x, y)] += summand<T>(ghost_key(ti, tj, x, y));
    }
  return all;
}

template <class T>
void check_sum(HaloExchanger& hx, const TileSetup& s) {
  for (int w = 0; w <= std::min(8, s.max_width()); ++w) {
    Field<T> f = sum_input<T>(s, s.i, s.j, w);
    hx.sum(f, w);
    const std::vector<T> all = folded<T>(s, w);
    const TileGeom& g = s.g;
    Mismatches m;
    for_storage(g, [&](int x, int y) {
      if (owned(g, x, y))
        m.check("owned", x, y, f(x, y), all[g.global_index(x, y)]);
      else if (in_ring(g, w, x, y))
        m.check("ghost", x, y, f(x, y), T{});
      else
        m.check("untouched", x, y, f(x, y), marker<T>());
    });
    EXPECT_EQ(m.count(), 0) << "sum tile (" << s.i << ", " << s.j << "), w " << w << ":\n"
                            << m.text();
  }
}

// ---- the tests, for each configuration --------------------------------------

class Halo : public Dist, public ::testing::WithParamInterface<Config> {
 protected:
  void SetUp() override {
    if (GetParam().ranks != 0 && GetParam().ranks != world_size())
      GTEST_SKIP() << "runs with " << GetParam().ranks << " ranks";
  }
};

TEST_P(Halo, NeighboursAreTheCartesianOnes) {
  const TileSetup s(GetParam());
  const HaloExchanger hx(s.cart, s.g);
  const auto rank_at = [&](int i, int j) {
    int coords[2] = {(i + s.d.px) % s.d.px, (j + s.d.py) % s.d.py}, r = -1;
    MPI_Cart_rank(s.cart, coords, &r);
    return r;
  };
  EXPECT_EQ(hx.left(), rank_at(s.i - 1, s.j));
  EXPECT_EQ(hx.right(), rank_at(s.i + 1, s.j));
  EXPECT_EQ(hx.down(), rank_at(s.i, s.j - 1));
  EXPECT_EQ(hx.up(), rank_at(s.i, s.j + 1));
}

TEST_P(Halo, FillMatchesPeriodicWrap) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  check_fill<std::int64_t>(hx, s, false);
  check_fill<float>(hx, s, false);
  check_fill<double>(hx, s, false);
}

TEST_P(Halo, SplitFillEqualsFill) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  check_fill<std::int64_t>(hx, s, true);
  check_fill<float>(hx, s, true);
  check_fill<double>(hx, s, true);
  // Bit for bit the same storage as fill().
  const int w = s.max_width();
  Field<float> a = fill_input<float>(s.g), b = a;
  hx.fill(a, w);
  hx.begin_fill(b, w);
  hx.finish_fill(b, w);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
}

TEST_P(Halo, SumMatchesPeriodicFold) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  check_sum<std::int64_t>(hx, s);
  check_sum<float>(hx, s);
  check_sum<double>(hx, s);
}

// A device backend stages only the halo frame through the host (the CUDA
// backend's ghosts()): pack the device field's frame into a host field whose
// other cells are garbage, exchange there, and unpack the frame back. The
// result must be the exchange of the whole field, bit for bit, and the bytes
// staged are the frame's, twice (there and back).
template <class T>
void check_staged(HaloExchanger& hx, const TileSetup& s) {
  for (int w = 1; w <= std::min(8, s.max_width()); ++w)
    for (const bool sum : {false, true}) {
      Field<T> whole = sum ? sum_input<T>(s, s.i, s.j, w) : fill_input<T>(s.g);
      Field<T> device = whole;
      Field<T> host(s.g, static_cast<T>(-12345));  // what was staged before
      if (sum)
        hx.sum(whole, w);
      else
        hx.fill(whole, w);
      const HaloFrame fr{s.g.nx, s.g.ny, w};
      std::vector<T> pinned(fr.size());
      long long staged = 0;
      pack_frame(device, fr, pinned.data());
      unpack_frame(pinned.data(), fr, host);
      staged += static_cast<long long>(fr.size() * sizeof(T));
      if (sum)
        hx.sum(host, w);
      else
        hx.fill(host, w);
      pack_frame(host, fr, pinned.data());
      unpack_frame(pinned.data(), fr, device);
      staged += static_cast<long long>(fr.size() * sizeof(T));
      EXPECT_EQ(std::memcmp(whole.data(), device.data(), whole.size() * sizeof(T)), 0)
          << (sum ? "sum" : "fill") << " w " << w;
      // The strips: the ghost ring within w and the owned ring within w.
      const long long nx = s.g.nx, ny = s.g.ny;
      const long long ring =
          (nx + 2 * w) * (ny + 2 * w) - std::max(0LL, nx - 2 * w) * std::max(0LL, ny - 2 * w);
      EXPECT_EQ(staged, 2 * ring * static_cast<long long>(sizeof(T)));
      // Never more than the whole padded field (equal on tiles no wider
      // than 2 w, where the frame is the whole tile and its ghosts).
      EXPECT_LE(staged, 2 * static_cast<long long>(s.g.size() * sizeof(T)));
    }
}

TEST_P(Halo, StagingTheFrameEqualsStagingTheWholeField) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  check_staged<std::int64_t>(hx, s);
  check_staged<float>(hx, s);
}

// fill() after sum() on the same field: the folded owned values reach every
// ghost (the pattern of a scatter step followed by a stencil).
TEST_P(Halo, SumThenFill) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  const int w = s.max_width();
  Field<std::int64_t> f = sum_input<std::int64_t>(s, s.i, s.j, w);
  hx.sum(f, w);
  hx.fill(f, w);
  const std::vector<std::int64_t> all = folded<std::int64_t>(s, w);
  Mismatches m;
  for (int y = -w; y < s.g.ny + w; ++y)
    for (int x = -w; x < s.g.nx + w; ++x)
      m.check("cell", x, y, f(x, y), all[s.g.global_index(x, y)]);
  EXPECT_EQ(m.count(), 0) << m.text();
}

// Each exchange sends one message per direction (two per phase), also to a
// rank that is its own neighbour: 4 per fill or sum.
TEST_P(Halo, Stats) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  EXPECT_EQ(hx.stats().messages, 0);
  EXPECT_EQ(hx.stats().bytes, 0);
  const int w = s.max_width();
  const long long cells = 2LL * w * s.g.ny + 2LL * w * (s.g.nx + 2 * w);
  Field<std::int64_t> a = fill_input<std::int64_t>(s.g);
  hx.fill(a, w);
  EXPECT_EQ(hx.stats().messages, 4);
  EXPECT_EQ(hx.stats().bytes, cells * 8);
  Field<float> b = fill_input<float>(s.g);
  hx.begin_fill(b, w);
  EXPECT_EQ(hx.stats().messages, 6);  // the x phase is posted
  hx.finish_fill(b, w);
  EXPECT_EQ(hx.stats().messages, 8);
  EXPECT_EQ(hx.stats().bytes, cells * 12);
  hx.sum(a, w);
  EXPECT_EQ(hx.stats().messages, 12);
  EXPECT_EQ(hx.stats().bytes, cells * 20);
  hx.reset_stats();
  EXPECT_EQ(hx.stats().messages, 0);
  EXPECT_EQ(hx.stats().bytes, 0);
  // Width 0 sends nothing.
  hx.fill(a, 0);
  hx.sum(a, 0);
  hx.begin_fill(b, 0);
  hx.finish_fill(b, 0);
  EXPECT_EQ(hx.stats().messages, 0);
}

TEST_P(Halo, InvalidWidthsThrowOnEveryRank) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  Field<double> f = fill_input<double>(s.g);
  const int too_wide = s.max_width() + 1;
  for (const int w : {-1, too_wide, s.g.halo + 1}) {
    EXPECT_THROW(hx.fill(f, w), std::invalid_argument) << "w " << w;
    EXPECT_THROW(hx.sum(f, w), std::invalid_argument) << "w " << w;
    EXPECT_THROW(hx.begin_fill(f, w), std::invalid_argument) << "w " << w;
  }
  // The message says why.
  try {
    hx.fill(f, too_wide);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("width " + std::to_string(too_wide)), std::string::npos)
        << e.what();
  }
  // A field of another geometry.
  TileGeom other = s.g;
  other.nx += 1;
  other.pitch = padded_pitch(other.nx, other.halo);
  Field<double> wrong(other);
  EXPECT_THROW(hx.fill(wrong, 1), std::invalid_argument);
  // Misuse of the split fill.
  EXPECT_THROW(hx.finish_fill(f, 1), std::logic_error);
  hx.begin_fill(f, 1);
  EXPECT_THROW(hx.begin_fill(f, 1), std::logic_error);
  EXPECT_THROW(hx.sum(f, 1), std::logic_error);
  hx.finish_fill(f, 1);
  // Nothing is left in flight: a valid exchange still works.
  f = fill_input<double>(s.g);
  hx.fill(f, s.max_width());
  expect_filled(f, s.max_width(), "fill after errors");
}

// ---- a device backend's two paths (dist/halo_path.h) --------------------------

// The host-staged path, step by step as the CUDA backend takes it, with host
// fields standing for the device's: two fields of different types and
// widths share one staging buffer (frame_layout); a split fill downloads at
// begin_fill, exchanges and uploads at finish_fill; a fill's upload writes
// the ghosts only. The device fields end as the exchange of the whole fields
// leaves them, bit for bit, and the staged bytes are staged_bytes'.
class StagedDevice {
 public:
  StagedDevice(HaloExchanger& hx, const TileGeom& g, int w64, int w32)
      : hx_(hx), g_(g), host64_(g, marker<std::int64_t>() + 1), host32_(g, marker<float>() + 1) {
    const int widths[2] = {w64, w32};
    const std::size_t elems[2] = {sizeof(std::int64_t), sizeof(float)};
    layout_ = frame_layout(g, widths, elems);
    pinned_.assign(layout_.bytes, 0);
    list_[0] = {&host64_, w64};
    list_[1] = {&host32_, w32};
  }
  // One ghost operation on the "device" fields d64 and d32.
  void run(GhostOp op, Field<std::int64_t>& d64, Field<float>& d32) {
    const StagingSteps s = staging_steps(op);
    if (s.download) {
      pack_frame(d64, layout_.slots[0].frame, at<std::int64_t>(0));
      pack_frame(d32, layout_.slots[1].frame, at<float>(1));
      staged += staged_bytes({true, false, GhostOp::kFill, false, false}, layout_);
    }
    if (s.exchange) {
      unpack_frame(at<std::int64_t>(0), layout_.slots[0].frame, host64_);
      unpack_frame(at<float>(1), layout_.slots[1].frame, host32_);
      if (s.exchange_op == GhostOp::kSum)
        hx_.sum(list_);
      else
        hx_.fill(list_);
    }
    if (s.upload) {
      pack_frame(host64_, layout_.slots[0].frame, at<std::int64_t>(0));
      pack_frame(host32_, layout_.slots[1].frame, at<float>(1));
      unpack_frame(at<std::int64_t>(0), layout_.slots[0].frame, d64, s.ghosts_only);
      unpack_frame(at<float>(1), layout_.slots[1].frame, d32, s.ghosts_only);
      staged += staged_bytes({false, false, GhostOp::kFill, true, false}, layout_);
    }
  }
  const FrameLayout& layout() const { return layout_; }
  long long staged = 0;

 private:
  template <class T>
  T* at(int slot) {
    return reinterpret_cast<T*>(pinned_.data() +
                                layout_.slots[static_cast<std::size_t>(slot)].offset);
  }
  HaloExchanger& hx_;
  TileGeom g_;
  Field<std::int64_t> host64_;
  Field<float> host32_;
  FrameLayout layout_;
  std::vector<unsigned char> pinned_;
  Ghosts list_[2];
};

// The owned cells within w of the edge set to the marker: an upload that
// wrote them would show.
template <class T>
void mark_owned_frame(Field<T>& f, int w) {
  const TileGeom& g = f.geom();
  const HaloFrame fr{g.nx, g.ny, w};
  for (std::size_t i = 0; i < fr.size(); ++i) {
    int x, y;
    fr.cell(i, x, y);
    if (fr.owned(x, y)) f(x, y) = marker<T>();
  }
}

template <class T>
void expect_same(const Field<T>& got, const Field<T>& want, const std::string& what) {
  EXPECT_EQ(std::memcmp(got.data(), want.data(), got.size() * sizeof(T)), 0) << what;
}

TEST_P(Halo, StagedStepsGiveTheExchangeOfTheWholeFields) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  const int w64 = s.max_width(), w32 = std::max(1, s.max_width() - 1);
  StagedDevice dev(hx, s.g, w64, w32);
  const long long frames = static_cast<long long>(dev.layout().payload);
  // Fill and split fill.
  for (const bool split : {false, true}) {
    Field<std::int64_t> d64 = fill_input<std::int64_t>(s.g), want64 = d64;
    Field<float> d32 = fill_input<float>(s.g), want32 = d32;
    hx.fill(want64, w64);
    hx.fill(want32, w32);
    dev.staged = 0;
    if (split) {
      dev.run(GhostOp::kBeginFill, d64, d32);
      // Interior work runs here; the upload must not write owned cells.
      mark_owned_frame(d64, w64);
      mark_owned_frame(d32, w32);
      mark_owned_frame(want64, w64);
      mark_owned_frame(want32, w32);
      dev.run(GhostOp::kFinishFill, d64, d32);
    } else {
      dev.run(GhostOp::kFill, d64, d32);
    }
    const std::string what = split ? "split fill" : "fill";
    expect_same(d64, want64, what + " int64");
    expect_same(d32, want32, what + " float");
    EXPECT_EQ(dev.staged, 2 * frames) << what;
  }
  // Sum (the frames' owned cells change: uploaded whole).
  Field<std::int64_t> d64 = sum_input<std::int64_t>(s, s.i, s.j, w64), want64 = d64;
  Field<float> d32 = sum_input<float>(s, s.i, s.j, w32), want32 = d32;
  hx.sum(want64, w64);
  hx.sum(want32, w32);
  dev.staged = 0;
  dev.run(GhostOp::kSum, d64, d32);
  expect_same(d64, want64, "sum int64");
  expect_same(d32, want32, "sum float");
  EXPECT_EQ(dev.staged, 2 * frames);
}

// The device-direct path's protocol with host memory standing for device
// memory: a packer that reads and writes only the fields' "device" copies
// (Ghosts::device: raw storage in the TileGeom layout, as the CUDA
// backend's buffers) and its own message buffers. The exchange must route
// every cell through it (the host fields stay as they were) and give the
// same bits as the host exchange.
class CopyPacker final : public HostBufferPacker {
 public:
  void pack(std::span<const Ghosts> parts, const RectOf& rect, char* p) override {
    each_row(parts, rect, [&](auto* cell, int n) {
      const std::size_t bytes = static_cast<std::size_t>(n) * sizeof(*cell);
      std::memcpy(p, cell, bytes);
      p += bytes;
    });
  }
  void unpack(std::span<const Ghosts> parts, const RectOf& rect, const char* p, bool add) override {
    each_row(parts, rect, [&](auto* cell, int n) {
      for (int x = 0; x < n; ++x, p += sizeof(*cell)) {
        std::remove_reference_t<decltype(*cell)> v;
        std::memcpy(&v, p, sizeof v);
        cell[x] = add ? cell[x] + v : v;
      }
    });
  }
  void zero(std::span<const Ghosts> parts, const RectOf& rect) override {
    each_row(parts, rect, [&](auto* cell, int n) {
      for (int x = 0; x < n; ++x) cell[x] = {};
    });
  }
  void ready() override { ++ready_calls; }
  int ready_calls = 0;

 private:
  // f(first cell of the row, cells) for every row of every field's rectangle.
  template <class F>
  static void each_row(std::span<const Ghosts> parts, const RectOf& rect, F&& f) {
    for (const Ghosts& g : parts) {
      if (g.width <= 0) continue;
      std::visit(
          [&](auto* host) {
            using T = typename std::remove_reference_t<decltype(*host)>::value_type;
            T* base = static_cast<T*>(g.device);
            const TileGeom& geo = host->geom();
            const Rect r = rect(g.width);
            for (int y = r.y0; y < r.y1; ++y) f(base + geo.at(r.x0, y), r.x1 - r.x0);
          },
          g.field);
    }
  }
};

TEST_P(Halo, PackerMovesTheDeviceCopiesOnly) {
  const TileSetup s(GetParam());
  HaloExchanger hx(s.cart, s.g);
  CopyPacker packer;
  const int w = s.max_width();
  for (const GhostOp op : {GhostOp::kFill, GhostOp::kBeginFill, GhostOp::kSum}) {
    const bool sum = op == GhostOp::kSum;
    Field<std::int64_t> d64 = sum ? sum_input<std::int64_t>(s, s.i, s.j, w)
                                  : fill_input<std::int64_t>(s.g),
                        want64 = d64;
    Field<float> d32 = sum ? sum_input<float>(s, s.i, s.j, w) : fill_input<float>(s.g),
                 want32 = d32;
    if (sum) {
      hx.sum(want64, w);
      hx.sum(want32, w);
    } else {
      hx.fill(want64, w);
      hx.fill(want32, w);
    }
    // The host fields only name type and geometry: never read, never written.
    Field<std::int64_t> name64(s.g, marker<std::int64_t>());
    Field<float> name32(s.g, marker<float>());
    const Field<std::int64_t> name64_before = name64;
    const Field<float> name32_before = name32;
    const Ghosts list[2] = {{&name64, w, d64.data()}, {&name32, w, d32.data()}};
    hx.set_packer(&packer);
    packer.ready_calls = 0;
    if (sum) {
      hx.sum(list);
    } else if (op == GhostOp::kFill) {
      hx.fill(list);
    } else {
      hx.begin_fill(list);
      EXPECT_THROW(hx.set_packer(nullptr), std::logic_error);  // not while in flight
      hx.finish_fill(list);
    }
    hx.set_packer(nullptr);
    const std::string what = sum ? "sum" : op == GhostOp::kFill ? "fill" : "split fill";
    expect_same(d64, want64, what + " int64");
    expect_same(d32, want32, what + " float");
    expect_same(name64, name64_before, what + " host int64 untouched");
    expect_same(name32, name32_before, what + " host float untouched");
    EXPECT_EQ(packer.ready_calls, 2) << what << ": one per phase, before MPI reads";
  }
}

TEST_F(Dist, MpiCudaSupportFollowsTheHeadersAndTheVariable) {
  const MpiCudaSupport s = mpi_cuda_support();
#if defined(MPIX_CUDA_AWARE_SUPPORT) && MPIX_CUDA_AWARE_SUPPORT
  EXPECT_TRUE(s.built);
#else
  EXPECT_FALSE(s.built);
  // Not built CUDA-aware (Debian's Open MPI): several tiles on a device
  // stage through the host.
  EXPECT_EQ(choose_halo_path(true, 2, s), HaloPath::kHostStaged);
#endif
  ::setenv("ERG_CUDA_AWARE_MPI", "0", 1);
  EXPECT_FALSE(mpi_cuda_support().allowed);
  EXPECT_EQ(choose_halo_path(true, 2, mpi_cuda_support()), HaloPath::kHostStaged);
  ::unsetenv("ERG_CUDA_AWARE_MPI");
  EXPECT_TRUE(mpi_cuda_support().allowed);
}

const Config kConfigs[] = {
    {"auto_37x23", 37, 23, 0, 0, 8, 0},       {"auto_50x31", 50, 31, 0, 0, 8, 0},
    {"auto_50x31_halo3", 50, 31, 0, 0, 3, 0},  // w up to the halo exactly
    {"auto_7x5", 7, 5, 0, 0, 8, 0},            // w up to the whole tile
    {"row_Px1_37x23", 37, 23, -1, 1, 8, 0},   {"column_1xP_37x23", 37, 23, 1, -1, 8, 0},
    {"uneven_Px1_10x9", 10, 9, -1, 1, 8, 0},  // 4 ranks: 3, 3, 3, 1 columns
    {"uneven_1xP_9x10", 9, 10, 1, -1, 8, 0},  {"grid_2x2_37x23", 37, 23, 2, 2, 8, 4},
    {"grid_2x2_50x31", 50, 31, 2, 2, 8, 4},   {"grid_3x1_37x23", 37, 23, 3, 1, 8, 3},
    {"grid_1x3_50x31", 50, 31, 1, 3, 8, 3},   {"grid_2x1_37x23", 37, 23, 2, 1, 8, 2},
};
INSTANTIATE_TEST_SUITE_P(Tiles, Halo, ::testing::ValuesIn(kConfigs), config_name);

// ---- construction -----------------------------------------------------------

TEST_F(Dist, RejectsCommunicatorsWithoutPeriodicCartesianTopology) {
  const TileSetup s(37, 23, 0, 0, 8);
  EXPECT_THROW(HaloExchanger(MPI_COMM_WORLD, s.g), std::invalid_argument);
  MPI_Comm open = MPI_COMM_NULL;
  int dims[2] = {s.d.px, s.d.py}, periods[2] = {1, 0};
  MPI_Cart_create(MPI_COMM_WORLD, 2, dims, periods, 0, &open);
  EXPECT_THROW(HaloExchanger(open, s.g), std::invalid_argument);
  MPI_Comm_free(&open);
}

TEST_F(Dist, RejectsInconsistentTiles) {
  // Tile 0 claims one row more than its left/right neighbours have (with
  // one tile along x: a pitch too short for its row). The neighbours see it,
  // and every rank throws, none waits for the others.
  const TileSetup s(37, 23, -1, 1, 4);
  TileGeom g = s.g;
  if (s.d.px == 1)
    g.pitch = g.nx + 2 * g.halo - 1;
  else if (s.i == 0)
    g.ny += 1;
  EXPECT_THROW(HaloExchanger(s.cart, g), std::invalid_argument);
}

// ---- the coarse window of the wind warping ----------------------------------

// Every tile's window (its coarse cells and a halo that may be wider than
// any tile and than the torus) holds the wrapped global coarse cells, on
// uneven tiles, strips and square-ish grids; one rank's window is the
// periodic one.
TEST_F(Dist, CoarseWindowIsTheWrappedGlobalGrid) {
  const auto value = [](int x, int y) { return 1000.0 * y + x + 0.25; };
  for (const int px : {0, -1}) {
    const TileSetup s(61, 23, px, px < 0 ? 1 : 0, 1);  // 1 fine cell per coarse cell
    MpiExchange ex(s.cart, s.d, s.g, 1, 1);
    std::vector<double> mine(static_cast<size_t>(s.g.nx) * s.g.ny);
    for (int y = 0; y < s.g.ny; ++y)
      for (int x = 0; x < s.g.nx; ++x)
        mine[static_cast<size_t>(y) * s.g.nx + x] = value(s.g.x0 + x, s.g.y0 + y);
    for (const auto& [hx, hy] : {std::pair{0, 0}, {3, 2}, {40, 29}, {3, 55}}) {
      std::vector<double> window;
      ex.coarse_window(mine, s.g.nx, s.g.ny, hx, hy, window);
      const int wx = s.g.nx + 2 * hx, wy = s.g.ny + 2 * hy;
      ASSERT_EQ(window.size(), static_cast<size_t>(wx) * wy);
      int wrong = 0;
      for (int j = 0; j < wy; ++j)
        for (int i = 0; i < wx; ++i) {
          const int gx = ((s.g.x0 - hx + i) % 61 + 61) % 61;
          const int gy = ((s.g.y0 - hy + j) % 23 + 23) % 23;
          wrong += window[static_cast<size_t>(j) * wx + i] != value(gx, gy);
        }
      EXPECT_EQ(wrong, 0) << "halo " << hx << " x " << hy << " on " << s.d.px << " x " << s.d.py
                          << " tiles, tile (" << s.i << ", " << s.j << ")";
      if (world_size() == 1) {
        PeriodicExchange one;
        std::vector<double> wrapped;
        one.coarse_window(mine, s.g.nx, s.g.ny, hx, hy, wrapped);
        EXPECT_TRUE(wrapped == window) << "halo " << hx << " x " << hy;
      }
    }
  }
}

// Prints the failures of ranks other than 0, whose default printer is off.
class RankFailurePrinter : public ::testing::EmptyTestEventListener {
 public:
  explicit RankFailurePrinter(int rank) : rank_(rank) {}
  void OnTestPartResult(const ::testing::TestPartResult& r) override {
    if (!r.failed()) return;
    std::fprintf(stderr, "[rank %d] %s:%d: Failure\n%s\n", rank_,
                 r.file_name() ? r.file_name() : "?", r.line_number(), r.message());
    std::fflush(stderr);
  }

 private:
  int rank_;
};

}  // namespace
}  // namespace erg::dist

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  ::testing::InitGoogleTest(&argc, argv);
  const int rank = erg::dist::world_rank();
  ::testing::TestEventListeners& listeners = ::testing::UnitTest::GetInstance()->listeners();
  if (rank != 0) {
    delete listeners.Release(listeners.default_result_printer());
    listeners.Append(new erg::dist::RankFailurePrinter(rank));
  }
  const int mine = RUN_ALL_TESTS();
  int worst = 0;
  MPI_Allreduce(&mine, &worst, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return worst;
}
