// SPDX-License-Identifier: Apache-2.0
// `erg export`: the snapshot, the samples, the engine tiles, one writer per
// file (see export.h).
#include "export/export.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "io/run_files.h"

namespace erg::exporting {

namespace fs = std::filesystem;

namespace {
const char* layer_name(Layer l) {
  switch (l) {
    case Layer::kHeight:
      return "height";
    case Layer::kSand:
      return "sand";
    case Layer::kBedrock:
      return "bedrock";
    case Layer::kVegetation:
      return "vegetation";
  }
  return "?";
}

std::vector<long long> snapshot_steps(const std::string& dir) {
  std::vector<long long> steps;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(fs::path(dir) / "snapshots", ec)) {
    const std::string n = e.path().filename().string();
    // step_NNNNNNNN.h5 (at least 8 digits; more past step 99999999)
    if (n.size() < 16 || n.rfind("step_", 0) != 0 || n.substr(n.size() - 3) != ".h5") continue;
    const std::string digits = n.substr(5, n.size() - 8);
    if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 18) continue;
    const long long s = std::stoll(digits);
    steps.push_back(s);
  }
  std::sort(steps.begin(), steps.end());
  return steps;
}
}  // namespace

std::string snapshot_path(const std::string& dir, long long step) {
  if (!fs::is_directory(dir)) throw ExportError(dir + ": not a directory (an erg output dir)");
  const auto steps = snapshot_steps(dir);
  if (steps.empty())
    throw ExportError(dir + ": no snapshots (expected snapshots/step_NNNNNNNN.h5)");
  if (step < 0) step = steps.back();
  if (!std::binary_search(steps.begin(), steps.end(), step)) {
    std::string have;
    for (std::size_t k = 0; k < steps.size() && k < 20; ++k)
      have += (k ? ", " : "") + std::to_string(steps[k]);
    if (steps.size() > 20) have += ", ...";
    throw ExportError("--step " + std::to_string(step) + ": " + dir +
                      " has no snapshot of that step; steps: " + have);
  }
  return (fs::path(dir) / "snapshots" / (step_name(step) + ".h5")).string();
}

std::string tile_path(const std::string& out, int i, int j) {
  const fs::path p(out);
  return (p.parent_path() / (p.stem().string() + "_x" + std::to_string(i) + "_y" +
                             std::to_string(j) + p.extension().string()))
      .string();
}

std::vector<std::string> run_export(const Request& r) {
  if (r.upsample < 1 || r.upsample > 64)
    throw ExportError("--upsample " + std::to_string(r.upsample) + ": allowed 1 to 64");
  if (r.tiles_x < 1 || r.tiles_y < 1) throw ExportError("--tiles: N and M must be at least 1");
  const io::Snapshot snap = io::read_snapshot(snapshot_path(r.dir, r.step), true);
  const int nx = snap.meta.nx, ny = snap.meta.ny;
  const Region reg = r.region.w > 0 ? r.region : Region{0, 0, nx, ny};
  if (reg.w <= 0 || reg.h <= 0 || reg.w > nx || reg.h > ny || reg.x0 < 0 || reg.y0 < 0 ||
      reg.x0 >= nx || reg.y0 >= ny)
    throw ExportError("--region " + std::to_string(reg.x0) + "," + std::to_string(reg.y0) + "," +
                      std::to_string(reg.w) + "," + std::to_string(reg.h) +
                      ": X0, Y0 must lie in the world [0, " + std::to_string(nx) + ") x [0, " +
                      std::to_string(ny) + ") and 1 <= W <= " + std::to_string(nx) +
                      ", 1 <= H <= " + std::to_string(ny) + " (cells; the region may wrap)");
  int fnx = 0, fny = 0;
  const bool amplified = r.amplify && r.layer == Layer::kHeight && r.upsample > 1;
  const std::vector<float> all =
      amplified ? amplified_heights(snapshot_path(r.dir, r.step), reg, r.upsample, &fnx, &fny)
                : heights_for_export(snap, r.layer, reg, r.upsample, &fnx, &fny);
  const int W = fnx - 1, H = fny - 1;  // samples without the shared extra row/column
  if (r.tiles_x > W || r.tiles_y > H)
    throw ExportError("--tiles " + std::to_string(r.tiles_x) + "x" + std::to_string(r.tiles_y) +
                      ": more tiles than samples (" + std::to_string(W) + " x " +
                      std::to_string(H) + ")");
  const double pixel = snap.meta.cell_size_m / r.upsample;
  Provenance p;
  p.job_spec_json = snap.meta.job_spec_json;
  p.step = snap.meta.step;
  p.time_days = snap.meta.time_days;
  p.layer = layer_name(r.layer);
  p.erg_version = snap.meta.erg_version;
  // One scale for every tile of a PNG export, so that tiles meet exactly.
  const auto [lo, hi] = std::minmax_element(all.begin(), all.end());

  const bool tiled = r.tiled || r.tiles_x > 1 || r.tiles_y > 1;
  // The OBJ mesh closes the region with the extra row and column; the images
  // of an untiled export are exactly the region's samples.
  const bool closed = r.format == Format::kObj;
  std::vector<std::string> written;
  for (int j = 0; j < r.tiles_y; ++j)
    for (int i = 0; i < r.tiles_x; ++i) {
      // Tile (i, j): x{i} counts from the west, y{j} from the north (image
      // order, as Unreal's tiled landscape import expects). Each tile holds
      // one more column and row than its share, shared with its neighbour.
      const int jj = r.tiles_y - 1 - j;  // from the south
      const int c0 = static_cast<int>(static_cast<long long>(i) * W / r.tiles_x);
      const int c1 = static_cast<int>(static_cast<long long>(i + 1) * W / r.tiles_x);
      const int r0 = static_cast<int>(static_cast<long long>(jj) * H / r.tiles_y);
      const int r1 = static_cast<int>(static_cast<long long>(jj + 1) * H / r.tiles_y);
      Field f;
      f.nx = (c1 - c0) + (tiled || closed ? 1 : 0);
      f.ny = (r1 - r0) + (tiled || closed ? 1 : 0);
      f.pixel_m = pixel;
      // Sample (0, 0) of the export sits at cell (x0, y0)'s south-west
      // corner + half a sample: the field's origin is that corner.
      f.x0_m = reg.x0 * snap.meta.cell_size_m + c0 * pixel;
      f.y0_m = reg.y0 * snap.meta.cell_size_m + r0 * pixel;
      f.v.resize(static_cast<std::size_t>(f.nx) * f.ny);
      for (int y = 0; y < f.ny; ++y)
        for (int x = 0; x < f.nx; ++x)
          f.v[static_cast<std::size_t>(y) * f.nx + x] =
              all[static_cast<std::size_t>(r0 + y) * fnx + (c0 + x)];
      const std::string path = tiled ? tile_path(r.out, i, j) : r.out;
      switch (r.format) {
        case Format::kGeoTiff:
          write_geotiff(path, f, p);
          break;
        case Format::kPng16:
          write_png16_export(path, f, p, *lo, *hi);
          written.push_back(path + ".json");
          break;
        case Format::kExr:
          write_exr(path, f, p);
          break;
        case Format::kObj:
          write_obj(path, f, p, r.normals);
          break;
      }
      written.push_back(path);
    }
  return written;
}

}  // namespace erg::exporting
