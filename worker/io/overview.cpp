// SPDX-License-Identifier: Apache-2.0
// The overview pyramid of a snapshot (io.h OverviewPyramid; cf.h
// write_overview): 2x-downsampled levels of the terrain, so that a preview or
// a dashboard of a run of any size reads kilobytes instead of the whole
// field. The levels are computed in sim/overview.cpp; this file stores and
// reads them.
#include <hdf5_hl.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/fields.h"
#include "io/cf.h"
#include "io/formats.h"
#include "io/hdf5_util.h"
#include "io/io.h"

namespace erg::io {

using detail::check;
using detail::checked;
using detail::close_checked;
using detail::Hid;

namespace {

constexpr const char* kGroup = "overview";
// The layers of a level, as the registry names them at level 0.
constexpr fields::Id kLayers[] = {fields::kBedrock, fields::kSand, fields::kVegetation};

std::string level_group(int level) {
  return std::string(kGroup) + "/level_" + std::to_string(level);
}

int blocks(int n, int level) {
  return static_cast<int>((static_cast<long long>(n) + (1LL << level) - 1) >> level);
}

const std::vector<float>& values_of(const OverviewLevel& l, fields::Id id) {
  return id == fields::kBedrock ? l.bedrock : id == fields::kSand ? l.sand : l.vegetation;
}

// Block centres along one axis of n cells: the middle of the cells a block
// covers (the last block may be partial).
std::vector<double> block_centres(int n, int level, double cell_m) {
  const long long s = 1LL << level;
  std::vector<double> c(static_cast<std::size_t>(blocks(n, level)));
  for (std::size_t b = 0; b < c.size(); ++b) {
    const long long lo = static_cast<long long>(b) * s, hi = std::min<long long>(n, lo + s);
    c[b] = 0.5 * static_cast<double>(lo + hi) * cell_m;
  }
  return c;
}

}  // namespace

int overview_levels(int nx, int ny) {
  int l = 0;
  while (blocks(nx, l) > 1 || blocks(ny, l) > 1) ++l;
  return l;
}

int overview_level_for(int nx, int ny, int max_px) {
  int l = 0;
  while (std::max(blocks(nx, l), blocks(ny, l)) > std::max(max_px, 1)) ++l;
  return l;
}

namespace detail {
void write_overview(hid_t file, const SnapshotMeta& meta, const OverviewPyramid& pyramid,
                    hid_t dxpl, bool write_values, const std::string& path) {
  Hid top = checked(H5Gcreate2(file, kGroup, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose, path,
                    "cannot create group /overview");
  write_attr_i64(top.get(), "levels", static_cast<std::int64_t>(pyramid.size()), path);
  write_attr_str(top.get(), "description",
                 "level_L: means over blocks of 2^L x 2^L cells (the last block of a row or "
                 "column partial), from exact integer sums",
                 path);
  close_checked(top, path, "cannot close /overview");
  Hid time = checked(H5Dopen2(file, "time", H5P_DEFAULT), H5Dclose, path, "cannot open /time");
  for (const OverviewLevel& l : pyramid) {
    const std::string gname = level_group(l.level);
    Hid g = checked(H5Gcreate2(file, gname.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                    H5Gclose, path, "cannot create group /" + gname);
    write_attr_i64(g.get(), "level", l.level, path);
    write_attr_i64(g.get(), "block_cells", std::int64_t{1} << l.level, path);
    write_attr_f64(g.get(), "block_size_m", std::ldexp(meta.cell_size_m, l.level), path);
    write_attr_i64(g.get(), "nx", l.nx, path);
    write_attr_i64(g.get(), "ny", l.ny, path);
    write_cf_coordinate(
        g.get(), {"y", "y (northward) of the block centre", "m", "projection_y_coordinate", "Y"},
        block_centres(meta.ny, l.level, meta.cell_size_m), dxpl, write_values, path);
    write_cf_coordinate(
        g.get(), {"x", "x (eastward) of the block centre", "m", "projection_x_coordinate", "X"},
        block_centres(meta.nx, l.level, meta.cell_size_m), dxpl, write_values, path);
    Hid y = checked(H5Dopen2(g.get(), "y", H5P_DEFAULT), H5Dclose, path, "cannot open y");
    Hid x = checked(H5Dopen2(g.get(), "x", H5P_DEFAULT), H5Dclose, path, "cannot open x");
    const std::vector<hsize_t> dims = {1, static_cast<hsize_t>(l.ny), static_cast<hsize_t>(l.nx)};
    for (const fields::Id id : kLayers) {
      const fields::Info& f = fields::info(id);
      const std::string what = "dataset '/" + gname + "/" + f.name + "'";
      Hid space = checked(H5Screate_simple(3, dims.data(), nullptr), H5Sclose, path,
                          "dataspace for " + what);
      // Chunks of at most 256 x 256 blocks, as the serial layers.
      const std::vector<hsize_t> chunk = {1, std::min<hsize_t>(dims[1], 256),
                                          std::min<hsize_t>(dims[2], 256)};
      Hid dcpl = deflate_dcpl(chunk, kSnapshotDeflate, path);
      Hid dset = checked(H5Dcreate2(g.get(), f.name, H5T_IEEE_F32LE, space.get(), H5P_DEFAULT,
                                    dcpl.get(), H5P_DEFAULT),
                         H5Dclose, path, "cannot create " + what);
      Hid fspace = checked(H5Dget_space(dset.get()), H5Sclose, path, "dataspace of " + what);
      const hsize_t held = static_cast<hsize_t>(l.bnx) * static_cast<hsize_t>(l.bny);
      const hsize_t mem_n = std::max<hsize_t>(held, 1);
      Hid mem =
          checked(H5Screate_simple(1, &mem_n, nullptr), H5Sclose, path, "memory space for " + what);
      if (held == 0) {
        check(H5Sselect_none(fspace.get()), path, "H5Sselect_none");
        check(H5Sselect_none(mem.get()), path, "H5Sselect_none");
      } else {
        const hsize_t start[3] = {0, static_cast<hsize_t>(l.y0), static_cast<hsize_t>(l.x0)};
        const hsize_t count[3] = {1, static_cast<hsize_t>(l.bny), static_cast<hsize_t>(l.bnx)};
        check(H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr),
              path, "cannot select the blocks of " + what);
      }
      static const float kNothing = 0;
      const float* buf = held ? values_of(l, id).data() : &kNothing;
      check(H5Dwrite(dset.get(), H5T_NATIVE_FLOAT, mem.get(), fspace.get(), dxpl, buf), path,
            "cannot write " + what);
      check(H5DSattach_scale(dset.get(), time.get(), 0), path, "cannot attach /time to " + what);
      check(H5DSattach_scale(dset.get(), y.get(), 1), path, "cannot attach y to " + what);
      check(H5DSattach_scale(dset.get(), x.get(), 2), path, "cannot attach x to " + what);
      write_attr_str(dset.get(), "units", f.unit, path);
      write_attr_str(dset.get(), "long_name",
                     std::string(f.snapshot.long_name) + ", mean over 2^" +
                         std::to_string(l.level) + " x 2^" + std::to_string(l.level) + " cells",
                     path);
      if (*f.snapshot.standard_name)
        write_attr_str(dset.get(), "standard_name", f.snapshot.standard_name, path);
      write_attr_str(dset.get(), "cell_methods", "x: y: mean", path);
      close_checked(dset, path, "cannot close " + what);
    }
    close_checked(x, path, "cannot close x");
    close_checked(y, path, "cannot close y");
    close_checked(g, path, "cannot close /" + gname);
  }
  close_checked(time, path, "cannot close /time");
}
}  // namespace detail

OverviewLevel read_overview_level(const std::string& path, int level) {
  detail::Hdf5Guard guard;
  detail::Hid file = detail::open_hdf5_readonly(path, "snapshot");
  const std::string gname = level_group(level);
  if (level < 1 || !detail::link_exists(file.get(), kGroup) ||
      !detail::link_exists(file.get(), gname))
    detail::fail(path, "no overview level " + std::to_string(level) +
                           " (snapshots carry /overview/level_1 ... level_N)");
  OverviewLevel l;
  l.level = level;
  detail::Hid g = detail::checked(H5Gopen2(file.get(), gname.c_str(), H5P_DEFAULT), H5Gclose, path,
                                  "cannot open /" + gname);
  const std::int64_t nx = detail::read_attr_i64(g.get(), "nx", path),
                     ny = detail::read_attr_i64(g.get(), "ny", path);
  if (nx <= 0 || ny <= 0 || nx > (1 << 24) || ny > (1 << 24))
    detail::fail(path, "/" + gname + " has a grid of " + std::to_string(nx) + " x " +
                           std::to_string(ny) + " blocks");
  l.nx = l.bnx = static_cast<int>(nx);
  l.ny = l.bny = static_cast<int>(ny);
  const std::vector<hsize_t> dims = {1, static_cast<hsize_t>(ny), static_cast<hsize_t>(nx)};
  for (const fields::Id id : kLayers) {
    std::vector<float>& v = id == fields::kBedrock ? l.bedrock
                            : id == fields::kSand  ? l.sand
                                                   : l.vegetation;
    v = detail::read_dataset<float>(g.get(), fields::info(id).name, H5T_NATIVE_FLOAT, dims, path);
  }
  return l;
}

}  // namespace erg::io
