// SPDX-License-Identifier: Apache-2.0
// Parallel HDF5 snapshots and checkpoints, run under mpirun with 1 to 4 ranks:
// files written tile by tile are the files the serial writers make (same
// datasets, types, attributes, filters; values bitwise, read back by the
// serial readers), chunked by tile; a checkpoint reads back in parallel under
// any tiling; a failure on any one rank (bad arguments, ranks that disagree,
// a failed rename, no directory, a full disk) throws the same IoError on every
// rank, leaves the previous file byte-identical and no temporary.
//
// Every test is collective: all ranks run it in step. Checks that only rank 0
// makes (reading files serially) live in helper functions, so that an ASSERT
// there returns from the helper, never past a collective call of the test.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "checkpoint_sample.h"
#include "io/io.h"
#include "test_util.h"

namespace erg::io {
namespace {

namespace fs = std::filesystem;
using testing::read_bytes;

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

int world_size() {
  int n = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

std::string bcast_string(std::string s, int root = 0) {
  int n = static_cast<int>(s.size());
  MPI_Bcast(&n, 1, MPI_INT, root, MPI_COMM_WORLD);
  s.resize(static_cast<std::size_t>(n));
  MPI_Bcast(s.data(), n, MPI_CHAR, root, MPI_COMM_WORLD);
  return s;
}

// One scratch directory for all ranks: rank 0 makes it (a TempDir named after
// the test) and removes it once every rank is done.
class SharedDir {
 public:
  SharedDir() {
    std::string p;
    if (world_rank() == 0) {
      dir_ = std::make_unique<testing::TempDir>();
      p = dir_->str();
    }
    path_ = bcast_string(p);
  }
  ~SharedDir() {
    MPI_Barrier(MPI_COMM_WORLD);
    dir_.reset();
  }
  SharedDir(const SharedDir&) = delete;
  SharedDir& operator=(const SharedDir&) = delete;

  std::string file(const std::string& name) const { return path_ + "/" + name; }
  // Rank 0 only (the others hold no TempDir).
  bool has_temporaries() const { return dir_->has_temporaries(); }
  std::set<std::string> entries() const { return dir_->entries(); }

 private:
  std::unique_ptr<testing::TempDir> dir_;
  std::string path_;
};

// ---- tilings ---------------------------------------------------------------------

// px x py tiles of ceil(n / p) cells, the last in each direction smaller; rank r
// owns tile (r % px, r / px); ranks beyond px * py own nothing.
struct Layout {
  int px = 1, py = 1;
};

int block(int n, int p) {
  return (n + p - 1) / p;
}

TileSlab tile_of(const Layout& l, int nx, int ny, int r) {
  TileSlab s;
  if (r >= l.px * l.py) return s;
  const int bx = block(nx, l.px), by = block(ny, l.py);
  const int ix = r % l.px, iy = r / l.px;
  s.x0 = std::min(ix * bx, nx);
  s.y0 = std::min(iy * by, ny);
  s.nx = std::clamp(nx - ix * bx, 0, bx);
  s.ny = std::clamp(ny - iy * by, 0, by);
  return s;
}

// The most nearly square px x py = ranks, px >= py: 1x1, 2x1, 3x1, 2x2.
Layout square_layout(int ranks) {
  int py = static_cast<int>(std::sqrt(static_cast<double>(ranks)));
  while (ranks % py != 0) --py;
  return {ranks / py, py};
}

std::string layout_text(const Layout& l) {
  return std::to_string(l.px) + "x" + std::to_string(l.py);
}

// The cells of `s` out of a global [ny][nx][components] array.
template <class T>
std::vector<T> cut(const std::vector<T>& global, int nx, const TileSlab& s, int components = 1) {
  std::vector<T> out;
  for (int y = s.y0; y < s.y0 + s.ny; ++y) {
    const std::size_t row = (static_cast<std::size_t>(y) * nx + s.x0) * components;
    out.insert(out.end(), global.begin() + static_cast<std::ptrdiff_t>(row),
               global.begin() +
                   static_cast<std::ptrdiff_t>(row + static_cast<std::size_t>(s.nx) * components));
  }
  return out;
}

template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

// ---- reference data --------------------------------------------------------------

// A global snapshot; values chosen so that bit patterns matter (-0, a
// denormal, a NaN with payload) besides ordinary exact ones.
struct GlobalSnapshot {
  SnapshotMeta meta;
  std::vector<float> bedrock, sand, vegetation, wind, airborne, shadow;

  GlobalSnapshot(int nx, int ny) {
    meta.step = 1234567890123;
    meta.time_days = 12.75;
    meta.cell_size_m = 0.5;
    meta.nx = nx;
    meta.ny = ny;
    meta.job_spec_json = "{\"name\": \"test \xc3\xbc\", \"grid\": {\"nx\": " + std::to_string(nx) +
                         "},\n \"quote\": \"\\\"\"}";
    meta.erg_version = "0.1.0";
    meta.unit_m = 1.0 / 4294967296.0;
    meta.sand_units_total = "123456789012345678901234567890";
    meta.bedrock_units_total = "-42";
    meta.airborne_units_total = "0";
    meta.seed = std::numeric_limits<std::uint64_t>::max() - 58;
    meta.backend = "cpu";
    for (int y = 0; y < ny; ++y) {
      for (int x = 0; x < nx; ++x) {
        bedrock.push_back(static_cast<float>(y * 100 + x) + 0.25f);
        sand.push_back(static_cast<float>((x * 7 + y * 3) % 11) * 0.5f);
        vegetation.push_back(static_cast<float>((x + y) % 5) / 4.0f);
        wind.push_back(static_cast<float>(x) - 18.5f);
        wind.push_back(static_cast<float>(y) * 0.125f - 1.0f);
        airborne.push_back(static_cast<float>(x) / 1024.0f);
        shadow.push_back(static_cast<float>(x % 2));
      }
    }
    bedrock[0] = -0.0f;
    sand[1] = 1e-40f;
    vegetation[2] = std::bit_cast<float>(std::uint32_t{0x7fc01234});
  }
};

// The tile of one rank, with pointers into it.
struct SnapshotTile {
  std::vector<float> bedrock, sand, vegetation, wind, airborne, shadow;
  SnapshotTile(const GlobalSnapshot& g, const TileSlab& s)
      : bedrock(cut(g.bedrock, g.meta.nx, s)),
        sand(cut(g.sand, g.meta.nx, s)),
        vegetation(cut(g.vegetation, g.meta.nx, s)),
        wind(cut(g.wind, g.meta.nx, s, 2)),
        airborne(cut(g.airborne, g.meta.nx, s)),
        shadow(cut(g.shadow, g.meta.nx, s)) {}
  SnapshotFields fields(bool optional) const {
    SnapshotFields f;
    f[erg::fields::kBedrock].data = bedrock.data();
    f[erg::fields::kSand].data = sand.data();
    f[erg::fields::kVegetation].data = vegetation.data();
    f[erg::fields::kWindX] = {wind.data(), 2, 0};
    f[erg::fields::kWindY] = {wind.data(), 2, 1};
    if (optional) {
      f[erg::fields::kAirborne].data = airborne.data();
      f[erg::fields::kShadow].data = shadow.data();
    }
    return f;
  }
};

SnapshotFields global_fields(const GlobalSnapshot& g, bool optional) {
  SnapshotFields f;
  f[erg::fields::kBedrock].data = g.bedrock.data();
  f[erg::fields::kSand].data = g.sand.data();
  f[erg::fields::kVegetation].data = g.vegetation.data();
  f[erg::fields::kWindX] = {g.wind.data(), 2, 0};
  f[erg::fields::kWindY] = {g.wind.data(), 2, 1};
  if (optional) {
    f[erg::fields::kAirborne].data = g.airborne.data();
    f[erg::fields::kShadow].data = g.shadow.data();
  }
  return f;
}

Checkpoint checkpoint_tile(const Checkpoint& g, const TileSlab& s) {
  Checkpoint c;
  c.step = g.step;
  c.nx = g.nx;
  c.ny = g.ny;
  c.job_spec_json = g.job_spec_json;
  c.ledger = g.ledger;
  c.units[erg::fields::kBedrock] = cut(g.units[erg::fields::kBedrock], g.nx, s);
  c.units[erg::fields::kSand] = cut(g.units[erg::fields::kSand], g.nx, s);
  c.units[erg::fields::kAirborne] = cut(g.units[erg::fields::kAirborne], g.nx, s);
  c.reals[erg::fields::kVegetation] = cut(g.reals[erg::fields::kVegetation], g.nx, s);
  c.reals[erg::fields::kResistance] = cut(g.reals[erg::fields::kResistance], g.nx, s);
  return c;
}

void expect_checkpoint_equal(const Checkpoint& got, const Checkpoint& want,
                             const std::string& ctx) {
  EXPECT_EQ(got.step, want.step) << ctx;
  EXPECT_EQ(got.nx, want.nx) << ctx;
  EXPECT_EQ(got.ny, want.ny) << ctx;
  EXPECT_EQ(got.job_spec_json, want.job_spec_json) << ctx;
  EXPECT_EQ(got.ledger, want.ledger) << ctx;
  EXPECT_TRUE(same_bits(got.units[erg::fields::kBedrock], want.units[erg::fields::kBedrock]))
      << ctx << ": bedrock_units";
  EXPECT_TRUE(same_bits(got.units[erg::fields::kSand], want.units[erg::fields::kSand]))
      << ctx << ": sand_units";
  EXPECT_TRUE(same_bits(got.units[erg::fields::kAirborne], want.units[erg::fields::kAirborne]))
      << ctx << ": airborne_units";
  EXPECT_TRUE(same_bits(got.reals[erg::fields::kVegetation], want.reals[erg::fields::kVegetation]))
      << ctx << ": vegetation";
  EXPECT_TRUE(same_bits(got.reals[erg::fields::kResistance], want.reals[erg::fields::kResistance]))
      << ctx << ": resistance";
}

template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const IoError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("not an IoError: ") + e.what();
  }
  return "no exception";
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

// ---- the file as HDF5 sees it (rank 0, serial HDF5 calls) -------------------------

herr_t collect_name(hid_t, const char* name, const H5A_info_t*, void* out) {
  static_cast<std::vector<std::string>*>(out)->push_back(name);
  return 0;
}

herr_t collect_link(hid_t, const char* name, const H5L_info_t*, void* out) {
  static_cast<std::vector<std::string>*>(out)->push_back(name);
  return 0;
}

std::vector<std::string> attribute_names(hid_t obj, H5_index_t index) {
  std::vector<std::string> names;
  hsize_t idx = 0;
  if (H5Aiterate2(obj, index, H5_ITER_INC, &idx, collect_name, &names) < 0) {
    H5Eclear2(H5E_DEFAULT);
    return {"(not iterable)"};
  }
  return names;
}

std::vector<std::string> dataset_names(hid_t file) {
  std::vector<std::string> names;
  hsize_t idx = 0;
  H5Literate(file, H5_INDEX_NAME, H5_ITER_INC, &idx, collect_link, &names);
  return names;
}

std::vector<hsize_t> chunk_of(hid_t dset) {
  hid_t dcpl = H5Dget_create_plist(dset);
  hsize_t dims[8] = {};
  const int rank = H5Pget_layout(dcpl) == H5D_CHUNKED ? H5Pget_chunk(dcpl, 8, dims) : 0;
  H5Pclose(dcpl);
  return std::vector<hsize_t>(dims, dims + std::max(rank, 0));
}

// Filter ids and their first parameter (the deflate level), in order.
std::vector<std::pair<int, unsigned>> filters_of(hid_t dset) {
  hid_t dcpl = H5Dget_create_plist(dset);
  std::vector<std::pair<int, unsigned>> out;
  for (int i = 0; i < H5Pget_nfilters(dcpl); ++i) {
    unsigned flags = 0, cd[8] = {};
    std::size_t ncd = 8;
    char name[64];
    const int id = H5Pget_filter2(dcpl, static_cast<unsigned>(i), &flags, &ncd, cd, sizeof name,
                                  name, nullptr);
    out.emplace_back(id, ncd > 0 ? cd[0] : 0u);
  }
  H5Pclose(dcpl);
  return out;
}

// `parallel` holds what the serial writer's `serial` holds, with the same
// HDF5 types, shapes and filters, and the root attributes in the same order
// where creation order is tracked; its chunks are `chunk` (1 x chunk for the
// [1][ny][nx] snapshot layers).
void expect_same_contract(const std::string& serial, const std::string& parallel,
                          const std::vector<hsize_t>& chunk) {
  hid_t fs_ = H5Fopen(serial.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  hid_t fp = H5Fopen(parallel.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(fs_, 0);
  ASSERT_GE(fp, 0);
  const std::vector<std::string> attrs = attribute_names(fs_, H5_INDEX_NAME);
  EXPECT_EQ(attribute_names(fp, H5_INDEX_NAME), attrs);
  EXPECT_EQ(attribute_names(fp, H5_INDEX_CRT_ORDER), attribute_names(fs_, H5_INDEX_CRT_ORDER));
  for (const std::string& a : attrs) {
    hid_t as = H5Aopen(fs_, a.c_str(), H5P_DEFAULT), ap = H5Aopen(fp, a.c_str(), H5P_DEFAULT);
    if (ap < 0) {
      ADD_FAILURE() << "attribute " << a << " missing";
      H5Aclose(as);
      continue;
    }
    hid_t ts = H5Aget_type(as), tp = H5Aget_type(ap);
    EXPECT_GT(H5Tequal(ts, tp), 0) << "type of attribute " << a;
    H5Tclose(ts);
    H5Tclose(tp);
    H5Aclose(as);
    H5Aclose(ap);
  }
  const std::vector<std::string> dsets = dataset_names(fs_);
  EXPECT_EQ(dataset_names(fp), dsets);
  for (const std::string& d : dsets) {
    hid_t ds = H5Dopen2(fs_, d.c_str(), H5P_DEFAULT), dp = H5Dopen2(fp, d.c_str(), H5P_DEFAULT);
    if (dp < 0) {
      ADD_FAILURE() << "dataset " << d << " missing";
      H5Dclose(ds);
      continue;
    }
    hid_t ts = H5Dget_type(ds), tp = H5Dget_type(dp);
    EXPECT_GT(H5Tequal(ts, tp), 0) << "type of dataset " << d;
    H5Tclose(ts);
    H5Tclose(tp);
    hid_t ss = H5Dget_space(ds), sp = H5Dget_space(dp);
    hsize_t dims_s[3] = {}, dims_p[3] = {};
    const int rank = H5Sget_simple_extent_dims(ss, dims_s, nullptr);
    EXPECT_EQ(rank, H5Sget_simple_extent_dims(sp, dims_p, nullptr)) << d;
    EXPECT_TRUE(std::equal(dims_s, dims_s + 3, dims_p)) << "shape of " << d;
    H5Sclose(ss);
    H5Sclose(sp);
    EXPECT_EQ(filters_of(dp), filters_of(ds)) << "filters of " << d;
    std::vector<hsize_t> want = chunk;
    if (d == "x" || d == "y" || d == "time") {
      want.clear();  // the CF coordinates of a snapshot: contiguous
    } else if (rank == 3) {
      want.insert(want.begin(), 1);  // snapshot layers, [1][ny][nx]
    }
    EXPECT_EQ(chunk_of(dp), want) << "chunk of " << d;
    H5Dclose(ds);
    H5Dclose(dp);
  }
  H5Fclose(fs_);
  H5Fclose(fp);
}

void expect_snapshot_equal(const Snapshot& r, const GlobalSnapshot& g, bool optional) {
  EXPECT_EQ(r.meta.step, g.meta.step);
  EXPECT_EQ(r.meta.time_days, g.meta.time_days);
  EXPECT_EQ(r.meta.cell_size_m, g.meta.cell_size_m);
  EXPECT_EQ(r.meta.nx, g.meta.nx);
  EXPECT_EQ(r.meta.ny, g.meta.ny);
  EXPECT_EQ(r.meta.job_spec_json, g.meta.job_spec_json);
  EXPECT_EQ(r.meta.erg_version, g.meta.erg_version);
  EXPECT_EQ(r.meta.unit_m, g.meta.unit_m);
  EXPECT_EQ(r.meta.sand_units_total, g.meta.sand_units_total);
  EXPECT_EQ(r.meta.bedrock_units_total, g.meta.bedrock_units_total);
  EXPECT_EQ(r.meta.airborne_units_total, g.meta.airborne_units_total);
  EXPECT_EQ(r.meta.seed, g.meta.seed);
  EXPECT_EQ(r.meta.backend, g.meta.backend);
  EXPECT_TRUE(same_bits(r[erg::fields::kBedrock], g.bedrock)) << "bedrock";
  EXPECT_TRUE(same_bits(r[erg::fields::kSand], g.sand)) << "sand";
  EXPECT_TRUE(same_bits(r[erg::fields::kVegetation], g.vegetation)) << "vegetation";
  EXPECT_TRUE(same_bits(r.wind, g.wind)) << "wind";
  if (optional) {
    EXPECT_TRUE(same_bits(r[erg::fields::kAirborne], g.airborne)) << "airborne";
    EXPECT_TRUE(same_bits(r[erg::fields::kShadow], g.shadow)) << "shadow";
  } else {
    EXPECT_TRUE(r[erg::fields::kAirborne].empty());
    EXPECT_TRUE(r[erg::fields::kShadow].empty());
  }
}

// Rank 0: the parallel file read serially is the global snapshot, and has
// the serial writer's contract with one chunk per tile.
void check_snapshot_file(const SharedDir& dir, const std::string& path, const GlobalSnapshot& g,
                         bool optional, const std::vector<hsize_t>& chunk) {
  expect_snapshot_equal(read_snapshot(path), g, optional);
  const std::string serial = dir.file("serial.h5");
  write_snapshot(serial, g.meta, global_fields(g, optional));
  expect_same_contract(serial, path, chunk);
  fs::remove(serial);
  EXPECT_FALSE(dir.has_temporaries());
}

// ---- snapshots ---------------------------------------------------------------------

class ParallelSnapshot : public ::testing::TestWithParam<std::pair<int, int>> {};

TEST_P(ParallelSnapshot, SerialReaderSeesTheGlobalFieldsAndContract) {
  const auto [nx, ny] = GetParam();
  SharedDir dir;
  const GlobalSnapshot g(nx, ny);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, world_rank());
  const SnapshotTile t(g, slab);
  const int cx = block(nx, l.px), cy = block(ny, l.py);
  const std::string path = dir.file("snap.h5");
  for (bool optional : {true, false}) {
    write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, t.fields(optional), slab, cx, cy);
    if (world_rank() == 0) {
      SCOPED_TRACE(layout_text(l) + (optional ? " with optional layers" : " without"));
      check_snapshot_file(dir, path, g, optional,
                          {static_cast<hsize_t>(cy), static_cast<hsize_t>(cx)});
    }
    MPI_Barrier(MPI_COMM_WORLD);
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, ParallelSnapshot,
                         ::testing::Values(std::make_pair(37, 23), std::make_pair(64, 48)),
                         [](const auto& info) {
                           return std::to_string(info.param.first) + "x" +
                                  std::to_string(info.param.second);
                         });

// A rank that owns no cells still takes part (empty selection) and may pass
// null pointers; chunks larger than the grid are clamped to it.
TEST(ParallelSnapshotLayout, RanksWithoutCellsAndOversizedChunks) {
  const int nx = 37, ny = 23;
  SharedDir dir;
  const GlobalSnapshot g(nx, ny);
  // Every rank but the last owns a band of rows; the last owns nothing
  // (with one rank, that rank owns everything).
  const int ranks = world_size();
  const Layout l{1, std::max(1, ranks - 1)};
  const TileSlab slab = tile_of(l, nx, ny, world_rank());
  const SnapshotTile t(g, slab);
  SnapshotFields f = t.fields(true);
  if (slab.nx * slab.ny == 0) f = SnapshotFields{};  // all null
  const std::string path = dir.file("snap.h5");
  write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, f, slab, 1000, block(ny, l.py));
  if (world_rank() == 0) {
    check_snapshot_file(dir, path, g, true,
                        {static_cast<hsize_t>(block(ny, l.py)), static_cast<hsize_t>(nx)});
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

// Chunks that do not line up with the tiles (several ranks share a chunk):
// slower, but the data must still be exact.
TEST(ParallelSnapshotLayout, ChunksNotAlignedWithTiles) {
  const int nx = 37, ny = 23;
  SharedDir dir;
  const GlobalSnapshot g(nx, ny);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, world_rank());
  const SnapshotTile t(g, slab);
  const std::string path = dir.file("snap.h5");
  write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, t.fields(true), slab, 10, 7);
  if (world_rank() == 0) check_snapshot_file(dir, path, g, true, {7, 10});
  MPI_Barrier(MPI_COMM_WORLD);
}

// An optional layer is written only when every rank that owns cells has it.
TEST(ParallelSnapshotLayout, OptionalLayerMissingOnOneRankIsLeftOut) {
  const int nx = 37, ny = 23;
  SharedDir dir;
  const GlobalSnapshot g(nx, ny);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, world_rank());
  const SnapshotTile t(g, slab);
  SnapshotFields f = t.fields(true);
  if (world_rank() == world_size() - 1) f[erg::fields::kAirborne].data = nullptr;
  const std::string path = dir.file("snap.h5");
  write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, f, slab, block(nx, l.px), block(ny, l.py));
  if (world_rank() == 0) {
    const Snapshot r = read_snapshot(path);
    EXPECT_TRUE(r[erg::fields::kAirborne].empty());
    EXPECT_TRUE(same_bits(r[erg::fields::kShadow], g.shadow));
    EXPECT_TRUE(same_bits(r[erg::fields::kBedrock], g.bedrock));
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

// ---- checkpoints -------------------------------------------------------------------

class ParallelCheckpoint : public ::testing::TestWithParam<std::pair<int, int>> {};

TEST_P(ParallelCheckpoint, SerialReaderSeesTheGlobalStateAndContract) {
  const auto [nx, ny] = GetParam();
  SharedDir dir;
  const Checkpoint g = testing::sample_checkpoint(nx, ny);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, world_rank());
  const int cx = block(nx, l.px), cy = block(ny, l.py);
  const std::string path = dir.file("ckpt.h5");
  write_checkpoint_parallel(MPI_COMM_WORLD, path, checkpoint_tile(g, slab), slab, cx, cy);
  if (world_rank() == 0) {
    expect_checkpoint_equal(read_checkpoint(path), g, "serial read of " + layout_text(l));
    const std::string serial = dir.file("serial.h5");
    write_checkpoint(serial, g);
    expect_same_contract(serial, path, {static_cast<hsize_t>(cy), static_cast<hsize_t>(cx)});
    fs::remove(serial);
    EXPECT_EQ(dir.entries(), std::set<std::string>{"ckpt.h5"});
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

// The file does not depend on the tiling that wrote it: read back under
// other tilings (transposed, fewer ranks with the rest idle, one row or
// column of tiles) and arbitrary, overlapping rectangles, every rank gets
// exactly its cells. A serially written checkpoint reads the same way.
TEST_P(ParallelCheckpoint, ReadsBackUnderAnyTiling) {
  const auto [nx, ny] = GetParam();
  SharedDir dir;
  const int rank = world_rank(), ranks = world_size();
  const Checkpoint g = testing::sample_checkpoint(nx, ny);
  const Layout wl = square_layout(ranks);
  const TileSlab wslab = tile_of(wl, nx, ny, rank);
  const std::string path = dir.file("ckpt.h5");
  write_checkpoint_parallel(MPI_COMM_WORLD, path, checkpoint_tile(g, wslab), wslab,
                            block(nx, wl.px), block(ny, wl.py));
  const std::string serial = dir.file("serial.h5");
  if (rank == 0) write_checkpoint(serial, g);
  MPI_Barrier(MPI_COMM_WORLD);

  std::vector<std::pair<std::string, TileSlab>> reads;
  for (const Layout& rl : {Layout{wl.py, wl.px}, Layout{1, ranks}, Layout{ranks, 1},
                           Layout{std::max(1, ranks - 1), 1}, Layout{1, std::max(1, ranks - 1)}}) {
    reads.emplace_back("tiling " + layout_text(rl), tile_of(rl, nx, ny, rank));
  }
  // Odd rectangles, overlapping between ranks, touching the far edges.
  TileSlab odd;
  odd.x0 = (7 * rank + 3) % nx;
  odd.y0 = (5 * rank + 1) % ny;
  odd.nx = nx - odd.x0;
  odd.ny = std::min(ny - odd.y0, 4 + rank);
  reads.emplace_back("rectangle", odd);
  reads.emplace_back("whole grid", TileSlab{0, 0, nx, ny});
  reads.emplace_back("nothing", TileSlab{});

  for (const std::string& file : {path, serial}) {
    for (const auto& [what, slab] : reads) {
      const std::string ctx =
          "rank " + std::to_string(rank) + ", " + what + " of " +
          (file == path ? std::string("parallel file written as ") + layout_text(wl)
                        : std::string("serial file"));
      const Checkpoint r = read_checkpoint_parallel(MPI_COMM_WORLD, file, slab);
      expect_checkpoint_equal(r, checkpoint_tile(g, slab), ctx);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, ParallelCheckpoint,
                         ::testing::Values(std::make_pair(37, 23), std::make_pair(64, 48)),
                         [](const auto& info) {
                           return std::to_string(info.param.first) + "x" +
                                  std::to_string(info.param.second);
                         });

// Written from a band source (what a run does: io::TileRows straight from
// the backend), a tall tile is asked for one band of rows at a time, never
// more than band_rows of its chunk height, and the file is the one written
// from whole arrays: same values, same checksums; read back band by band,
// the sink sees every cell of the slab once.
TEST(ParallelBands, CheckpointWrittenAndReadBandByBand) {
  const int nx = 40, ny = 300;
  SharedDir dir;
  Checkpoint g = testing::sample_checkpoint(nx, ny);
  // Every state field (a run's backend has them all).
  for (int i = 0; i < erg::fields::kCount; ++i) {
    const auto id = static_cast<erg::fields::Id>(i);
    if (!erg::fields::is_state(id) || g.size(id) > 0) continue;
    auto& v = g.reals[id];
    v.resize(static_cast<std::size_t>(nx) * ny);
    for (std::size_t c = 0; c < v.size(); ++c) v[c] = static_cast<float>(c % 7) * 0.5f;
  }
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, world_rank());
  const int cx = block(nx, l.px), cy = block(ny, l.py);
  Checkpoint tile = checkpoint_tile(g, slab);
  tile.reals[erg::fields::kObstacles] = cut(g.reals[erg::fields::kObstacles], g.nx, slab);
  Checkpoint header = tile;
  for (auto& v : header.units) v.clear();
  for (auto& v : header.reals) v.clear();
  int most = 0, calls = 0;
  const std::string path = dir.file("bands.h5");
  write_checkpoint_parallel(
      MPI_COMM_WORLD, path, header,
      [&](erg::fields::Id id, int y0, int y1, void* out) {
        most = std::max(most, y1 - y0);
        ++calls;
        const bool units = erg::fields::info(id).type == erg::fields::Type::kUnits;
        const std::size_t row = (units ? 8 : 4) * static_cast<std::size_t>(slab.nx);
        const char* from = units ? reinterpret_cast<const char*>(tile.units[id].data())
                                 : reinterpret_cast<const char*>(tile.reals[id].data());
        std::memcpy(out, from + row * y0, row * (y1 - y0));
      },
      slab, cx, cy);
  EXPECT_LE(most, erg::io::band_rows(cy));
  EXPECT_LE(most, erg::io::kBandRows);
  EXPECT_GT(calls, 6) << "several bands per field";
  if (world_rank() == 0) {
    // read_checkpoint verifies the checksums against the data.
    expect_checkpoint_equal(read_checkpoint(path), g, "banded write");
    const std::string whole = dir.file("whole.h5");
    write_checkpoint(whole, g);
    expect_same_contract(whole, path,
                         {static_cast<hsize_t>(erg::io::band_rows(cy)), static_cast<hsize_t>(cx)});
  }
  MPI_Barrier(MPI_COMM_WORLD);
  std::vector<int> seen(static_cast<std::size_t>(slab.nx) * std::max(slab.ny, 0), 0);
  int sink_most = 0;
  const Checkpoint r = read_checkpoint_parallel(
      MPI_COMM_WORLD, path, slab, [&](const Checkpoint& h) -> erg::io::TileRowsIn {
        EXPECT_EQ(h.nx, nx);
        EXPECT_EQ(h.step, g.step);
        return [&](erg::fields::Id id, int y0, int y1, const void*) {
          sink_most = std::max(sink_most, y1 - y0);
          if (id != erg::fields::kSand) return;
          for (int y = y0; y < y1; ++y)
            for (int x = 0; x < slab.nx; ++x) ++seen[static_cast<std::size_t>(y) * slab.nx + x];
        };
      });
  EXPECT_TRUE(r.units[erg::fields::kSand].empty());
  EXPECT_LE(sink_most, erg::io::kBandRows);
  for (const int n : seen) ASSERT_EQ(n, 1);
}

// ---- failures ------------------------------------------------------------------------

// Rank 0 puts `bytes` at `path`; afterwards checks it is still exactly that
// and that no temporary is left.
struct OldFile {
  const SharedDir& dir;
  std::string path, bytes;
  OldFile(const SharedDir& d, const std::string& p) : dir(d), path(p) {
    if (world_rank() == 0) {
      bytes = "the previous file, which must survive a failed write\n";
      testing::write_bytes(path, bytes);
    }
    MPI_Barrier(MPI_COMM_WORLD);
  }
  void expect_intact(const std::string& ctx) const {
    MPI_Barrier(MPI_COMM_WORLD);
    if (world_rank() != 0) return;
    EXPECT_EQ(read_bytes(path), bytes) << ctx;
    EXPECT_FALSE(dir.has_temporaries()) << ctx;
  }
};

// Every rank threw an IoError naming the path; `cause` is in the message.
void expect_failed_everywhere(const std::string& message, const std::string& path,
                              const std::string& cause) {
  EXPECT_TRUE(contains(message, path)) << message;
  EXPECT_TRUE(contains(message, cause)) << message;
  // All ranks report the same failure.
  const std::string root = bcast_string(message);
  EXPECT_EQ(message, root);
}

TEST(ParallelFailure, BadTileOnOneRankThrowsEverywhereAndKeepsTheOldFile) {
  const int nx = 37, ny = 23;
  SharedDir dir;
  const int rank = world_rank(), last = world_size() - 1;
  const GlobalSnapshot g(nx, ny);
  const Checkpoint gc = testing::sample_checkpoint(nx, ny);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, rank);
  const int cx = block(nx, l.px), cy = block(ny, l.py);
  const SnapshotTile t(g, slab);
  const std::string path = dir.file("out.h5");
  const OldFile old(dir, path);

  // A required layer missing on the last rank.
  SnapshotFields f = t.fields(true);
  if (rank == last) f[erg::fields::kBedrock].data = nullptr;
  std::string m =
      error_of([&] { write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, f, slab, cx, cy); });
  expect_failed_everywhere(m, path, "null pointer");
  old.expect_intact("null layer");

  // A checkpoint array of the wrong size on the last rank.
  Checkpoint c = checkpoint_tile(gc, slab);
  if (rank == last) c.units[erg::fields::kSand].pop_back();
  m = error_of([&] { write_checkpoint_parallel(MPI_COMM_WORLD, path, c, slab, cx, cy); });
  expect_failed_everywhere(m, path, "'sand_units'");
  old.expect_intact("short array");

  // A bad ledger (rejected as by the serial writer).
  c = checkpoint_tile(gc, slab);
  c.ledger.push_back({"bad", "12x"});
  m = error_of([&] { write_checkpoint_parallel(MPI_COMM_WORLD, path, c, slab, cx, cy); });
  expect_failed_everywhere(m, path, "not a decimal integer");
  old.expect_intact("bad ledger");

  // Invalid chunk sizes.
  m = error_of(
      [&] { write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, t.fields(true), slab, 0, cy); });
  expect_failed_everywhere(m, path, "invalid chunk");
  old.expect_intact("chunk");

  // Tiles that do not cover the grid exactly once.
  TileSlab bad = slab;
  if (rank == last) bad.nx -= 1;
  m = error_of([&] {
    write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, SnapshotTile(g, bad).fields(true), bad,
                            cx, cy);
  });
  expect_failed_everywhere(m, path, "cover");
  old.expect_intact("hole");
  if (world_size() > 1) {
    const TileSlab all{0, 0, nx, ny};
    const SnapshotTile whole(g, all);
    m = error_of([&] {
      write_snapshot_parallel(MPI_COMM_WORLD, path, g.meta, whole.fields(true), all, nx, ny);
    });
    expect_failed_everywhere(m, path, "overlaps");
    old.expect_intact("overlap");
  }
}

// Every rank must pass the same attribute values; a rank that does not is
// named, and nothing is written.
TEST(ParallelFailure, RanksThatDisagreeOnMetadataThrowEverywhere) {
  if (world_size() < 2) GTEST_SKIP() << "needs two ranks";
  const int nx = 37, ny = 23;
  SharedDir dir;
  const int rank = world_rank(), last = world_size() - 1;
  const GlobalSnapshot g(nx, ny);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, rank);
  const int cx = block(nx, l.px), cy = block(ny, l.py);
  const SnapshotTile t(g, slab);
  const std::string path = dir.file("out.h5");
  const OldFile old(dir, path);

  SnapshotMeta meta = g.meta;
  if (rank == last) meta.time_days = 13.0;
  std::string m = error_of(
      [&] { write_snapshot_parallel(MPI_COMM_WORLD, path, meta, t.fields(true), slab, cx, cy); });
  expect_failed_everywhere(m, path, "disagree on 'time_days'");
  EXPECT_TRUE(contains(m, "rank " + std::to_string(last))) << m;
  old.expect_intact("time_days");

  Checkpoint c = checkpoint_tile(testing::sample_checkpoint(nx, ny), slab);
  if (rank == last) c.ledger[1].second = "7";
  m = error_of([&] { write_checkpoint_parallel(MPI_COMM_WORLD, path, c, slab, cx, cy); });
  expect_failed_everywhere(m, path, "disagree on 'ledger_bedrock_eroded'");
  old.expect_intact("ledger");
}

// Failures inside the I/O itself: the rename on rank 0 alone (the path is a
// directory), and the file creation on every rank (no such directory).
TEST(ParallelFailure, IoFailuresThrowEverywhereAndLeaveNoTemporary) {
  const int nx = 37, ny = 23;
  SharedDir dir;
  const GlobalSnapshot g(nx, ny);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, nx, ny, world_rank());
  const SnapshotTile t(g, slab);
  const int cx = block(nx, l.px), cy = block(ny, l.py);

  const std::string busy = dir.file("busy.h5");
  if (world_rank() == 0) {
    fs::create_directory(busy);
    testing::write_bytes(busy + "/keep", "x");
  }
  MPI_Barrier(MPI_COMM_WORLD);
  std::string m = error_of(
      [&] { write_snapshot_parallel(MPI_COMM_WORLD, busy, g.meta, t.fields(true), slab, cx, cy); });
  expect_failed_everywhere(m, busy, "rename");
  MPI_Barrier(MPI_COMM_WORLD);
  if (world_rank() == 0) {
    EXPECT_TRUE(fs::is_directory(busy));
    EXPECT_EQ(read_bytes(busy + "/keep"), "x");
    EXPECT_FALSE(dir.has_temporaries());
  }

  const std::string nowhere = dir.file("no/such/dir/ckpt.h5");
  const Checkpoint c = checkpoint_tile(testing::sample_checkpoint(nx, ny), slab);
  m = error_of([&] { write_checkpoint_parallel(MPI_COMM_WORLD, nowhere, c, slab, cx, cy); });
  expect_failed_everywhere(m, nowhere, "cannot create temporary file");
  MPI_Barrier(MPI_COMM_WORLD);
  if (world_rank() == 0) {
    EXPECT_FALSE(dir.has_temporaries());
  }
}

// A 256 x 256 checkpoint of random values (incompressible: about 2 MB).
Checkpoint random_checkpoint(int n) {
  Checkpoint g;
  g.nx = n;
  g.ny = n;
  g.step = 1;
  std::mt19937_64 rng(3);
  const std::size_t cells = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
  for (std::size_t i = 0; i < cells; ++i) {
    g.units[erg::fields::kBedrock].push_back(static_cast<std::int64_t>(rng()));
    g.units[erg::fields::kSand].push_back(static_cast<std::int64_t>(rng()));
    g.units[erg::fields::kAirborne].push_back(static_cast<std::int64_t>(rng()));
    g.reals[erg::fields::kVegetation].push_back(
        std::bit_cast<float>(static_cast<std::uint32_t>(rng() >> 34)));
    g.reals[erg::fields::kResistance].push_back(
        std::bit_cast<float>(static_cast<std::uint32_t>(rng() >> 34)));
  }
  return g;
}

// A full disk (here: a file-size limit on every rank, which fails writes
// with EFBIG as a full disk fails them with ENOSPC) is found when rank 0
// reserves the file's space, before any collective write: every rank throws,
// the old file stays, no temporary is left, and the process exits cleanly
// (HDF5 1.10.8 would hang or crash in MPI_Finalize after a failed collective
// write).
TEST(ParallelFailure, FullDiskIsFoundBeforeWriting) {
  const int n = 256;
  SharedDir dir;
  const Checkpoint g = random_checkpoint(n);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, n, n, world_rank());
  const Checkpoint c = checkpoint_tile(g, slab);
  const std::string path = dir.file("ckpt.h5");
  const OldFile old(dir, path);
  std::string m;
  {
    testing::FileSizeLimit limit(512 * 1024);
    m = error_of([&] {
      write_checkpoint_parallel(MPI_COMM_WORLD, path, c, slab, block(n, l.px), block(n, l.py));
    });
  }
  expect_failed_everywhere(m, path, "cannot reserve");
  EXPECT_TRUE(contains(m, "File too large")) << m;
  old.expect_intact("file size limit");

  // The same write with room succeeds.
  write_checkpoint_parallel(MPI_COMM_WORLD, path, c, slab, block(n, l.px), block(n, l.py));
  if (world_rank() == 0) expect_checkpoint_equal(read_checkpoint(path), g, "after the failure");
  MPI_Barrier(MPI_COMM_WORLD);
}

// The reservation (an upper bound of the file's size) does not stay in the
// file: a compressible checkpoint ends up small.
TEST(ParallelCheckpointSize, ReservedSpaceIsGivenBack) {
  const int n = 256;
  SharedDir dir;
  Checkpoint g = random_checkpoint(n);
  for (auto* v : {&g.units[erg::fields::kBedrock], &g.units[erg::fields::kSand],
                  &g.units[erg::fields::kAirborne]}) {
    std::fill(v->begin(), v->end(), 7);
  }
  std::fill(g.reals[erg::fields::kVegetation].begin(), g.reals[erg::fields::kVegetation].end(),
            0.5f);
  std::fill(g.reals[erg::fields::kResistance].begin(), g.reals[erg::fields::kResistance].end(),
            0.0f);
  const Layout l = square_layout(world_size());
  const TileSlab slab = tile_of(l, n, n, world_rank());
  const std::string path = dir.file("ckpt.h5");
  write_checkpoint_parallel(MPI_COMM_WORLD, path, checkpoint_tile(g, slab), slab, block(n, l.px),
                            block(n, l.py));
  if (world_rank() == 0) {
    EXPECT_LT(fs::file_size(path), 100u * 1024u);
    expect_checkpoint_equal(read_checkpoint(path), g, "compressible");
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

// The parallel reader fails like the serial one, on every rank.
TEST(ParallelFailure, ReaderErrorsReachEveryRank) {
  const int nx = 37, ny = 23;
  SharedDir dir;
  const int rank = world_rank();
  const TileSlab slab = tile_of(square_layout(world_size()), nx, ny, rank);

  const std::string missing = dir.file("missing.h5");
  std::string m = error_of([&] { read_checkpoint_parallel(MPI_COMM_WORLD, missing, slab); });
  expect_failed_everywhere(m, missing, "No such file");

  const std::string junk = dir.file("junk.h5");
  if (rank == 0) testing::write_bytes(junk, std::string(4096, '\x5a'));
  MPI_Barrier(MPI_COMM_WORLD);
  m = error_of([&] { read_checkpoint_parallel(MPI_COMM_WORLD, junk, slab); });
  expect_failed_everywhere(m, junk, "not an HDF5 file");

  const GlobalSnapshot g(nx, ny);
  const std::string snap = dir.file("snap.h5");
  if (rank == 0) write_snapshot(snap, g.meta, global_fields(g, false));
  MPI_Barrier(MPI_COMM_WORLD);
  m = error_of([&] { read_checkpoint_parallel(MPI_COMM_WORLD, snap, slab); });
  expect_failed_everywhere(m, snap, "not an erg checkpoint");

  const std::string ckpt = dir.file("ckpt.h5");
  if (rank == 0) write_checkpoint(ckpt, testing::sample_checkpoint(nx, ny));
  MPI_Barrier(MPI_COMM_WORLD);
  TileSlab outside = slab;
  if (rank == world_size() - 1) outside.x0 = nx - outside.nx + 1;
  m = error_of([&] { read_checkpoint_parallel(MPI_COMM_WORLD, ckpt, outside); });
  expect_failed_everywhere(m, ckpt, "not inside the 37 x 23 grid");
}

// Prints the failures of ranks other than 0 (whose output is the usual one),
// prefixed with the rank.
class RankFailurePrinter : public ::testing::EmptyTestEventListener {
 public:
  explicit RankFailurePrinter(int rank) : rank_(rank) {}
  void OnTestPartResult(const ::testing::TestPartResult& r) override {
    if (!r.failed()) return;
    std::printf("[rank %d] %s:%d: Failure\n%s\n", rank_, r.file_name() ? r.file_name() : "?",
                r.line_number(), r.summary());
    std::fflush(stdout);
  }

 private:
  int rank_;
};

}  // namespace
}  // namespace erg::io

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  ::testing::InitGoogleTest(&argc, argv);
  const int rank = erg::io::world_rank();
  if (rank != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
    listeners.Append(new erg::io::RankFailurePrinter(rank));
  }
  int result = RUN_ALL_TESTS();
  // A failure on any rank fails the run on every rank.
  MPI_Allreduce(MPI_IN_PLACE, &result, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return result;
}
