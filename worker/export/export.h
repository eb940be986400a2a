// SPDX-License-Identifier: Apache-2.0
// Exports of a snapshot to the formats of GIS and game-engine tools:
// GeoTIFF (geotiff.cpp), 16-bit PNG + JSON sidecar (png16.cpp), OpenEXR
// (exr.cpp) and OBJ meshes (obj.cpp); the command `erg export` (export.cpp)
// picks the snapshot, samples the field (heights.cpp), cuts engine tiles and
// calls one writer per file. Every file is written atomically.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "io/io.h"

namespace erg::exporting {

struct ExportError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

enum class Layer { kHeight, kSand, kBedrock, kVegetation };
enum class Format { kGeoTiff, kPng16, kExr, kObj };

// A window of the world in cells (x0, y0: south-west cell; w, h: size).
// w = h = 0: the whole world. May wrap across the torus's edges.
struct Region {
  int x0 = 0, y0 = 0, w = 0, h = 0;
};

struct Request {
  std::string dir;      // an erg output directory
  long long step = -1;  // -1: the latest snapshot
  Format format = Format::kGeoTiff;
  Layer layer = Layer::kHeight;
  std::string out;  // output file
  Region region;
  int upsample = 1;  // samples per cell along each axis
  int tiles_x = 1, tiles_y = 1;
  bool tiled = false;    // --tiles given (even 1x1): engine tiles with shared borders
  bool normals = false;  // OBJ: write vertex normals
  // Layer height with upsample > 1: add ripples and sand bumps (worker/amplify/,
  // [P19 6]) on the upsampled samples. Off: plain bilinear interpolation.
  bool amplify = true;
};

// Samples of the exported layer: nx x ny, row-major, row 0 = south; sample
// (i, j) stands at x = x0_m + (i + 1/2) pixel_m, y = y0_m + (j + 1/2) pixel_m.
struct Field {
  int nx = 0, ny = 0;
  double pixel_m = 1;
  double x0_m = 0, y0_m = 0;
  std::vector<float> v;
};

// What every writer records about the source.
struct Provenance {
  std::string job_spec_json;
  long long step = 0;
  double time_days = 0;
  std::string layer;  // "height", "sand", ...
  std::string erg_version;
};

// THE place where the exported heights are made: the layer of `snap` over
// `region` (cells, whole world when w = h = 0), upsample samples per cell,
// with one extra column and row past the region's east and north edges
// taken from the torus (engine tiles and OBJ meshes share them). Returns
// (w * upsample + 1) x (h * upsample + 1) samples; *nx, *ny receive the
// size. upsample = 1 copies the snapshot's cells exactly; upsample > 1
// interpolates bilinearly between cell centres, periodically.
// run_export replaces these samples by amplified ones (amplified_heights)
// for layer kHeight with upsample > 1 unless Request::amplify is off.
std::vector<float> heights_for_export(const io::Snapshot& snap, Layer layer, const Region& region,
                                      int upsample, int* nx, int* ny);

// The amplified terrain [P19 6] of the snapshot file `path` on the same
// samples as heights_for_export(kHeight): (w * upsample + 1) x
// (h * upsample + 1), the extra column and row taken from the torus. The
// ripples see the snapshot's wind, shadow, vegetation, obstacles and the
// wind history of its job (amplify::input_from_snapshot).
std::vector<float> amplified_heights(const std::string& path, const Region& region, int upsample,
                                     int* nx, int* ny);

// The snapshot file of `step` in an output dir (-1: the latest).
std::string snapshot_path(const std::string& dir, long long step);

// Runs a whole export; returns the files written (one, or one per tile, and
// PNG sidecars).
std::vector<std::string> run_export(const Request& r);

// File name of tile (i, j) of `out`: "<out without extension>_x<i>_y<j><ext>".
std::string tile_path(const std::string& out, int i, int j);

// ---- writers (one file per format) ----------------------------------------------
// GeoTIFF float32, DEFLATE, PREDICTOR=3, tiled 256 x 256, pixel size = pixel_m,
// a LOCAL_CS in metres, metadata ERG_JOB_SPEC, ERG_STEP, ERG_TIME_DAYS, ERG_LAYER.
void write_geotiff(const std::string& path, const Field& f, const Provenance& p);
// 16-bit grey PNG, raw = round((v - offset_m) / metres_per_unit), and its
// sidecar `path + ".json"` with the scale and the Unreal / Unity settings.
// `lo`, `hi`: the value range mapped to 0 and 65535 (shared by all tiles).
void write_png16_export(const std::string& path, const Field& f, const Provenance& p, double lo,
                        double hi);
// OpenEXR, one FLOAT channel "Y", ZIP compression, first row = north.
void write_exr(const std::string& path, const Field& f, const Provenance& p);
// OBJ: one vertex per sample (metres), two triangles per quad, vertex
// normals when asked. Refuses more than kMaxObjVertices vertices.
inline constexpr long long kMaxObjVertices = 4097LL * 4097LL;
void write_obj(const std::string& path, const Field& f, const Provenance& p, bool normals);

}  // namespace erg::exporting
