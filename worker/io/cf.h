// SPDX-License-Identifier: Apache-2.0
// Internal to erg_io: what makes a snapshot a netCDF-4 file that follows the
// CF conventions (CF-1.10), so that netCDF tools (ncdump, xarray over
// h5netcdf, Panoply, ...) see real dimensions and coordinates rather than
// anonymous HDF5 arrays. Shared by the serial and the parallel snapshot
// writers; the layers, their units and names come from the field registry
// (core/fields.h).
//
// The layout (README "Snapshot contract"):
//   /time [1]        float64, simulated time since the start of the run (days)
//   /y    [ny]       float64, cell-centre y in metres ((j + 1/2) * cell_size_m)
//   /x    [nx]       float64, cell-centre x in metres ((i + 1/2) * cell_size_m)
//   /<layer> [1][ny][nx] float32, dimensions (time, y, x)
// /time, /y and /x are HDF5 dimension scales attached to every layer, which
// is how netCDF-4 stores dimensions and their coordinate variables.
#pragma once

#include <hdf5.h>

#include <string>
#include <vector>

#include "io/io.h"

namespace erg::io::detail {

// The simulated time of a snapshot, in days since the start of the run: the
// one place that decides which time a snapshot's CF coordinate and XDMF
// <Time> carry.
double snapshot_time_days(const SnapshotMeta& meta);

// Creates /time, /y and /x (contiguous float64 datasets, dimension scales,
// with their CF attributes), attaches them to the layers named (which must
// exist, shaped [1][ny][nx]) and gives each layer its units, long_name and
// standard_name from the field registry (core/fields.h); writes the global Conventions, title and
// source. The coordinate values are written with `dxpl` (H5P_DEFAULT, or a collective transfer list
// in the parallel writer, where only the rank with `write_values` selects them and the others take
// part with an empty selection). In the parallel writer every rank calls this with the same
// arguments (the metadata operations are collective).
void write_cf(hid_t file, const SnapshotMeta& meta, const std::vector<std::string>& layers,
              hid_t dxpl, bool write_values, const std::string& path);

// A 1-D float64 coordinate variable `name` in `loc` (a file or group), made a
// dimension scale of the same name, with its CF attributes; values written
// as write_cf writes its own (`dxpl`, `write_values`).
struct CfCoordinate {
  const char* name;
  const char* long_name;
  const char* units;
  const char* standard_name;
  const char* axis;
};
void write_cf_coordinate(hid_t loc, const CfCoordinate& c, const std::vector<double>& values,
                         hid_t dxpl, bool write_values, const std::string& path);

// The overview pyramid (io.h OverviewPyramid) as the groups
// /overview/level_L, each a CF grid of its own: coordinates x and y (block
// centres, metres), float32 bedrock, sand and vegetation [1][ny][nx] with the
// dimensions (/time, y, x) and the registry's units and names, and the
// attributes level, block_cells (2^L) and block_size_m; /overview holds
// levels (their number). Each caller writes the blocks its levels hold with
// `dxpl` (collectively in the parallel writer, where every rank calls this
// with its own blocks and coordinates come from the rank with
// `write_values`). Datasets are deflated in chunks of at most 256 x 256.
void write_overview(hid_t file, const SnapshotMeta& meta, const OverviewPyramid& pyramid,
                    hid_t dxpl, bool write_values, const std::string& path);

}  // namespace erg::io::detail
