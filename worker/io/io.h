// SPDX-License-Identifier: Apache-2.0
// Files a run writes and reads: HDF5 snapshots (+ XDMF sidecar), exact
// checkpoints, hillshaded PNG previews, and input maps (HDF5, 16-bit PNG).
//
// Every file is written to "<path>.tmp-<pid>" and renamed over <path> only
// when complete and flushed, so a reader (or a crash) never sees half a file.
// All 2-D arrays here are row-major [ny][nx] without halo; row 0 is y = 0.
#pragma once

#include <mpi.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/fields.h"
#include "io/io_error.h"

namespace erg::io {

// ---- snapshots -------------------------------------------------------------
// Root attributes of a snapshot file (the file contract in README.md).
struct SnapshotMeta {
  std::int64_t step = 0;
  double time_days = 0;
  double cell_size_m = 1;
  int nx = 0, ny = 0;
  std::string job_spec_json;  // the full, defaults-filled job spec
  std::string erg_version;
  double unit_m = 0;             // height of one integer unit, metres
  std::string sand_units_total;  // exact totals as decimal strings
  std::string bedrock_units_total;
  std::string airborne_units_total;
  std::uint64_t seed = 0;
  std::string backend;  // "cpu" or "cuda"
  // Physical time, the wind and the calibration (sim/calibration.h), written
  // as their own attributes by detail::write_physical_attrs.
  double time_s = 0;
  bool physical = false;          // wind in physical units (else model units)
  double shear_velocity_mps = 0;  // u* of the high-altitude wind at this step
  double wind_speed_mps = 0;      // model wind |a| at this step
  double wind_direction_deg = 0;  // towards, ccw from +x
  double dt_s = 0;                // time per step
  double threshold_mps = 0, reference_shear_velocity_mps = 0;
  double calibration_flux_m2_per_step = 0, calibration_law_flux_m2_per_s = 0;
  std::string flux_law;
  // The lowest and highest ground (bedrock + sand, float32 metres as the
  // layers hold them) over the whole domain, from a reduction over the tiles
  // (sim/overview.h): a dashboard's relief without reading the layers. NaN:
  // not known (not written).
  double ground_min_m = std::numeric_limits<double>::quiet_NaN();
  double ground_max_m = std::numeric_limits<double>::quiet_NaN();
};

// The values of one snapshot layer at the owned cells, row-major: data[stride
// * c + offset] for cell c (stride 2 and offset 0 or 1 pick a component of
// interleaved (x, y) pairs). Null data: the layer is not written.
struct LayerValues {
  const float* data = nullptr;
  int stride = 1, offset = 0;
};
// The layers of a snapshot, by registry field (core/fields.h): every field
// with a snapshot position, in that unit (units fields in metres). Required
// layers (not snapshot.optional) must be given.
struct SnapshotFields {
  std::array<LayerValues, fields::kCount> layer{};
  LayerValues& operator[](fields::Id id) { return layer[static_cast<std::size_t>(id)]; }
  const LayerValues& operator[](fields::Id id) const { return layer[static_cast<std::size_t>(id)]; }
};

// ---- overview pyramid ---------------------------------------------------------
// Level L of a snapshot's overview pyramid: the domain in blocks of 2^L x 2^L
// cells (block (i, j) covers cells [i 2^L, (i+1) 2^L) x [j 2^L, (j+1) 2^L),
// clipped to the domain: the last block of a row or column may be partial),
// each holding the mean bedrock, sand (metres) and vegetation of its cells.
// The means are computed from exact integer sums (sim/overview.h), so a level
// is bitwise the same for any tiling. A rank holds the blocks it owns: the
// rectangle x0, y0, bnx x bny of the level's grid (the whole grid on one
// process), row-major.
struct OverviewLevel {
  int level = 0;                                 // blocks of 2^level cells a side
  int nx = 0, ny = 0;                            // the level's grid: ceil(domain / 2^level)
  int x0 = 0, y0 = 0;                            // the first block held
  int bnx = 0, bny = 0;                          // blocks held
  std::vector<float> bedrock, sand, vegetation;  // [bny][bnx]
};
// Levels 1, 2, ... up to the one that is a single block (a domain of one cell
// has none). In the file: the group /overview/level_L (README "Snapshot
// contract").
using OverviewPyramid = std::vector<OverviewLevel>;
// The number of levels of a domain's pyramid: the smallest L with both
// ceil(nx / 2^L) and ceil(ny / 2^L) equal to 1.
int overview_levels(int nx, int ny);
// The finest level (0: the cells themselves) whose grid fits max_px on its
// longer side: the level a preview of at most max_px pixels is drawn from.
int overview_level_for(int nx, int ny, int max_px);
// Reads level L (>= 1) of a snapshot's pyramid: kilobytes for a preview of
// any domain. Throws IoError when the file has no such level.
OverviewLevel read_overview_level(const std::string& path, int level);

// Writes one float32 dataset [1][ny][nx] (dimensions time, y, x) per layer
// given, in the registry's snapshot order (bedrock, sand, vegetation, wind_x,
// wind_y, then the optional ones); deflate+shuffle, chunked; the coordinates
// /time /y /x and the CF metadata of the registry (a netCDF-4 file, io/cf.h);
// the root attributes of SnapshotMeta. Atomic (write then rename).
// With `pyramid` (sim/overview.h) its levels go in too.
void write_snapshot(const std::string& path, const SnapshotMeta& meta, const SnapshotFields& f,
                    const OverviewPyramid* pyramid = nullptr);

// XDMF sidecar so ParaView opens the snapshot: the grid in the X-Y plane,
// nodes at the cell centres (the CF x and y), node attributes height
// (bedrock + sand, ready for Warp By Scalar), then every layer of `layers`
// (registry fields, in snapshot order; wind_x and wind_y as one vector wind
// (x, y, 0)), and the simulated time in days. `h5_name` is the snapshot file
// name relative to the XDMF file. Atomic.
void write_xdmf(const std::string& xdmf_path, const std::string& h5_name, const SnapshotMeta& meta,
                const std::vector<fields::Id>& layers);
// The layers of a snapshot written from `f` (those given), in file order.
std::vector<fields::Id> snapshot_layer_ids(const SnapshotFields& f);
// The sidecar of an existing snapshot file, next to it (".h5" -> ".xdmf"),
// from the file's own attributes and datasets (erg fetch).
void write_xdmf_for(const std::string& h5_path);
// The sidecar of one overview level of a snapshot ("step_N.overview.xdmf"):
// a node per block on the level's spacing, with its bedrock, sand,
// vegetation and height, so ParaView opens a run of any size at a size it
// can draw. Atomic.
void write_overview_xdmf(const std::string& xdmf_path, const std::string& h5_name,
                         const SnapshotMeta& meta, int level);
// The level the overview sidecars show: the preview's (at most kPreviewMaxPx
// blocks a side), at least 1; 0 when the domain has no level (one cell).
int overview_xdmf_level(int nx, int ny);
// DIR/run.xdmf: a temporal collection of every DIR/snapshots/step_N.xdmf in
// step order, which ParaView opens as one animated run; DIR/overview.xdmf the
// same of the step_N.overview.xdmf sidecars. Atomic: rewritten whole after
// each snapshot, so a reader always sees a complete collection.
void write_run_xdmf(const std::string& dir);

// Reads a snapshot back (tests, tools): every layer of the registry that the
// file has, in its unit; files written before the CF layout ([ny][nx]
// layers, an interleaved /wind) are read too. Missing optional layers stay
// empty; terrain_only reads bedrock, sand and vegetation alone (what a
// preview needs: 12 of the 28 bytes per cell).
struct Snapshot {
  SnapshotMeta meta;
  std::array<std::vector<float>, fields::kCount> layers;
  std::vector<float> wind;  // wind_x and wind_y interleaved [ny][nx][2] (empty: terrain_only)
  const std::vector<float>& operator[](fields::Id id) const {
    return layers[static_cast<std::size_t>(id)];
  }
  std::vector<float>& operator[](fields::Id id) { return layers[static_cast<std::size_t>(id)]; }
};
Snapshot read_snapshot(const std::string& path, bool terrain_only = false);
// The root attributes alone (no layer is read): kilobytes for any domain.
SnapshotMeta read_snapshot_meta(const std::string& path);

// ---- heightmaps --------------------------------------------------------------
// One float32 dataset /height [ny][nx] (row 0 = y = 0, metres), deflated,
// with root attributes cell_size_m, nx, ny, `source` and the given numbers
// (step, region, upsample...). Atomic. Written by `erg amplify`.
struct HeightmapMeta {
  int nx = 0, ny = 0;
  double cell_size_m = 1;
  std::string source;                                 // e.g. the snapshot path
  std::vector<std::pair<std::string, double>> attrs;  // more root attributes
};
void write_heightmap(const std::string& path, const HeightmapMeta& meta, const float* height);

// ---- checkpoints -----------------------------------------------------------
// The exact integer state: enough to continue a run bitwise identically.
// Its arrays are the state fields of the registry (core/fields.h):
// units[id] (int64 units) or reals[id], row-major [ny][nx]. An optional
// field (checkpoint_optional) may be empty: not in the file (older files).
struct Checkpoint : fields::ByField<std::vector> {
  std::int64_t step = 0;
  int nx = 0, ny = 0;
  std::string job_spec_json;
  // Named 128-bit ledgers (e.g. sand added by events), as decimal strings.
  std::vector<std::pair<std::string, std::string>> ledger;
  // The number of values of field id (units or reals, by its type).
  std::size_t size(fields::Id id) const {
    return fields::info(id).type == fields::Type::kUnits ? units[id].size() : reals[id].size();
  }
};
void write_checkpoint(const std::string& path, const Checkpoint& c);  // atomic
Checkpoint read_checkpoint(const std::string& path);

// Grids longer than this (cells) on a side are box-averaged down to it.
constexpr int kPreviewMaxPx = 2048;
// ---- previews --------------------------------------------------------------
// Hillshaded PNG (8-bit RGB, one pixel per cell, north up): bare bedrock in
// grey, sand tinted from pale to deep ochre with thickness, vegetation green,
// lit from the north-west at 45 degrees with the true cell size (the domain is
// a torus: slopes wrap at the edges). Images wider than max_px are reduced by
// box-averaging. `vegetation` may be null (none). Atomic.
//
// With `labels` (the run's previews) it is a picture to read: at least 768 px
// on its long side (small grids upscaled, shaded at the output resolution
// from bilinear heights), with a panel below the map: a scale bar of a round
// number of metres, the colour legend of sand thickness, the step and
// simulated time, and a compass with the current wind's arrow (pointing
// where it blows) over the spokes of a multi-directional regime.
struct PreviewLabels {
  std::int64_t step = 0;
  double time_days = 0;
  double wind_x = 0, wind_y = 0;  // current wind, any speed unit (x east, y north)
  struct Spoke {
    double direction_deg;  // towards, counter-clockwise from east
    double weight;         // relative (probability, flux share)
  };
  std::vector<Spoke> rose;  // two or more: drawn; empty: one direction
};
void write_preview_png(const std::string& path, int nx, int ny, double cell_size_m,
                       const float* bedrock, const float* sand, const float* vegetation,
                       int max_px = kPreviewMaxPx, const PreviewLabels* labels = nullptr);
// Where a labelled preview puts things (pixels, image top-left origin).
struct PreviewLayout {
  int width = 0, height = 0;             // the whole image
  int map_w = 0, map_h = 0;              // the map, at the top-left
  double metres_per_px = 0;              // of the map
  double bar_m = 0;                      // the scale bar's length in metres ...
  int bar_x = 0, bar_y = 0, bar_px = 0;  // ... and where it is (white, 6 px high)
  int legend_x = 0, legend_y = 0, legend_w = 0, legend_h = 0;
  int label_x = 0;  // step and time
  int wind_cx = 0, wind_cy = 0, wind_r = 0;
};
PreviewLayout preview_layout(int nx, int ny, double cell_size_m, int max_px = 2048);

// ---- input maps ------------------------------------------------------------
// A 2-D map read as doubles, row-major [ny][nx], row 0 = y = 0 (south).
struct Map {
  int nx = 0, ny = 0;
  std::vector<double> values;
  // What the file says about itself (GeoTIFF: the geotransform and the
  // linear unit of its CRS; 0 / empty where the file does not say).
  double pixel_w = 0, pixel_h = 0;  // size of one pixel, in `units`
  std::string units;                // e.g. "metre"; empty: unknown
  double units_m = 0;               // metres per unit (0: unknown)
};
// HDF5: a 2-D dataset [ny][nx] of any integer or float type.
Map read_hdf5_map(const std::string& path, const std::string& dataset);
// 16-bit (or 8-bit) greyscale PNG; values normalised to [0, 1]. The first
// image row is the north edge (y = ny - 1), as in any image viewer. RGB and
// palette images read as Rec. 709 luminance of the stored values (no gamma);
// alpha is ignored.
Map read_png_map(const std::string& path);
// Any single-band raster GDAL reads (GeoTIFF first of all), band 1 as
// doubles, north-up images flipped so that row 0 = south; pixel size and
// units from the geotransform and the CRS's linear unit when georeferenced.
// Nodata pixels are an error (a hole in a DEM has no height to start from).
Map read_gdal_map(const std::string& path);
// OpenEXR: channel "Y", else "R", else the only channel, as float; the first
// image row is the north edge.
Map read_exr_map(const std::string& path);

// ---- fitting a map to the periodic grid (map_fit.cpp) ----------------------------
// Mean absolute jump across the seam that joins column nx-1 to column 0
// (axis 0) or row ny-1 to row 0 (axis 1), and the mean absolute jump between
// neighbouring pixels inside the map along the same axis.
struct Seam {
  double jump = 0;      // mean |v(last) - v(first)| over the seam
  double interior = 0;  // mean |v(i+1) - v(i)| inside the map
};
Seam seam_of(const Map& m, int axis);
// max - min of the values (0 for a constant map).
double range_of(const Map& m);
// Cross-fades each border with the opposite one over `wx` columns and `wy`
// rows (pixels of the map): the pixel at distance d < w from a seam becomes
// a v + (1 - a) v_mirror with a = 1/2 + d / (2 w), v_mirror the pixel at the
// same distance on the other side of the seam. Both sides of a seam then
// meet at their mean, so the map wraps without a step.
void blend_borders(Map& m, int wx, int wy);
// Bilinear resampling to nx x ny cells on the torus: cell centres are mapped
// onto the map's pixel centres with the map stretched over the whole domain,
// and interpolation wraps across the edges (the map is tileable). Same size:
// returned unchanged.
Map resample_periodic(const Map& m, int nx, int ny);

// 16-bit greyscale PNG writer (tests, exports): values in [0, 1], row 0 = south.
void write_png16(const std::string& path, int nx, int ny, const std::vector<double>& values01);

// ---- distributed (parallel HDF5) ---------------------------------------------
// The same files, written and read by every rank of a communicator, each with
// its tile of the global domain. Collective: every rank of `comm` calls with
// the same path, meta and chunk sizes. Arrays are the rank's owned cells,
// row-major [tile ny][tile nx]. Datasets are chunked tile by tile (chunk
// chunk_ny x chunk_nx; tiles start at multiples of the chunk) and compressed,
// written collectively through MPI-IO. Atomic: everything is written to a
// temporary name that rank 0 renames once every rank has closed the file; a
// crash of any rank leaves the previous file at `path` untouched.
struct TileSlab {
  int x0 = 0, y0 = 0;  // first owned cell, global coordinates
  int nx = 0, ny = 0;  // owned cells
};
// The writers and readers move a tile a band of rows at a time, never a
// whole field: a band is the height of a chunk, band_rows(chunk_ny) (the
// largest divisor of the chunk height that is at most kBandRows), so every
// collective write covers whole chunks of one rank.
inline constexpr int kBandRows = 64;
int band_rows(int chunk_ny);
// Rows [y0, y1) of the tile's owned cells of field `id` (tile-local rows),
// row-major [y1 - y0][slab.nx], into `out`: float metres for a snapshot
// layer, the stored type (int64 units or float) for a checkpoint field.
using TileRows = std::function<void(fields::Id id, int y0, int y1, void* out)>;
// The same, handed to the caller as they are read.
using TileRowsIn = std::function<void(fields::Id id, int y0, int y1, const void* in)>;
// Snapshot layers `layers` (registry fields in snapshot order, the same on
// every rank) drawn band by band from `rows`.
void write_snapshot_parallel(MPI_Comm comm, const std::string& path, const SnapshotMeta& meta,
                             const std::vector<fields::Id>& layers, const TileRows& rows,
                             const TileSlab& slab, int chunk_nx, int chunk_ny,
                             const OverviewPyramid* pyramid = nullptr);
// Every state field drawn band by band from `rows`; `header` gives step,
// grid, spec and ledger (its arrays are not read).
void write_checkpoint_parallel(MPI_Comm comm, const std::string& path, const Checkpoint& header,
                               const TileRows& rows, const TileSlab& slab, int chunk_nx,
                               int chunk_ny);
// Reads the header, then hands `start(header)`'s sink every state field the
// file has, band by band (the slab's cells), and verifies the checksums once
// all are read (an IoError after the sink saw corrupt bands: discard them).
// Returns the header (arrays empty). Collective.
Checkpoint read_checkpoint_parallel(MPI_Comm comm, const std::string& path, const TileSlab& slab,
                                    const std::function<TileRowsIn(const Checkpoint&)>& start);
// `pyramid`: the blocks of each level this rank owns (sim/overview.h); null on
// every rank or on none.
void write_snapshot_parallel(MPI_Comm comm, const std::string& path, const SnapshotMeta& meta,
                             const SnapshotFields& tile_fields, const TileSlab& slab, int chunk_nx,
                             int chunk_ny, const OverviewPyramid* pyramid = nullptr);
// c.nx, c.ny are the global size; c's arrays hold the tile (slab) only.
void write_checkpoint_parallel(MPI_Comm comm, const std::string& path, const Checkpoint& c,
                               const TileSlab& slab, int chunk_nx, int chunk_ny);
// Reads the cells of `slab` (any tiling: the file does not depend on the one
// that wrote it); the result's nx, ny are the global size and its arrays the
// slab's cells. Collective.
Checkpoint read_checkpoint_parallel(MPI_Comm comm, const std::string& path, const TileSlab& slab);

}  // namespace erg::io
