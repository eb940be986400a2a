// SPDX-License-Identifier: Apache-2.0
// Input maps as the job names them: see map_file.h.
#include "job/map_file.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "job/spec.h"

namespace erg::job {

namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

const char* format_name(erg::v1::MapFile::Format f) {
  switch (f) {
    case erg::v1::MapFile::HDF5:
      return "HDF5";
    case erg::v1::MapFile::PNG16:
      return "PNG";
    case erg::v1::MapFile::GEOTIFF:
      return "GeoTIFF";
    case erg::v1::MapFile::EXR:
      return "EXR";
    default:
      return "map";
  }
}

}  // namespace

erg::v1::MapFile::Format map_format(const erg::v1::MapFile& map, const std::string& file) {
  if (map.format() != erg::v1::MapFile::FORMAT_UNSPECIFIED) return map.format();
  std::string ext = std::filesystem::path(file).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".h5" || ext == ".hdf5" || ext == ".he5") return erg::v1::MapFile::HDF5;
  if (ext == ".png") return erg::v1::MapFile::PNG16;
  if (ext == ".tif" || ext == ".tiff") return erg::v1::MapFile::GEOTIFF;
  if (ext == ".exr") return erg::v1::MapFile::EXR;
  return erg::v1::MapFile::FORMAT_UNSPECIFIED;
}

static std::string default_dataset() {
  const auto* f = erg::v1::MapFile::descriptor()->FindFieldByName("dataset");
  return f->options().GetExtension(erg::v1::spec).default_text();
}

io::Map load_map(const erg::v1::MapFile& map, const erg::v1::JobSpec& spec,
                 const std::string& base_dir, std::string* note) {
  const std::string file = resolve_path(map.path(), base_dir);
  const std::string named = ".path = \"" + map.path() + "\"";
  const auto format = map_format(map, file);
  io::Map m;
  try {
    switch (format) {
      case erg::v1::MapFile::HDF5:
        // Unset before the defaults are applied (a job being checked): the
        // proto's default_text.
        m = io::read_hdf5_map(file, map.dataset().empty() ? default_dataset() : map.dataset());
        break;
      case erg::v1::MapFile::PNG16:
        m = io::read_png_map(file);
        break;
      case erg::v1::MapFile::GEOTIFF:
        m = io::read_gdal_map(file);
        break;
      case erg::v1::MapFile::EXR:
        m = io::read_exr_map(file);
        break;
      default:
        throw MapError(".format is unset and the extension of \"" + map.path() +
                       "\" is not .h5/.hdf5/.png/.tif/.tiff/.exr; set format to HDF5, PNG16, "
                       "GEOTIFF or EXR");
    }
  } catch (const io::IoError& e) {
    throw MapError(named + " cannot be read: " + e.what());
  }
  for (double v : m.values)
    if (!std::isfinite(v)) throw MapError(named + " contains a non-finite value");

  const int nx = static_cast<int>(spec.domain().nx()), ny = static_cast<int>(spec.domain().ny());
  const double cell = spec.domain().cell_size_m();
  // Size of one map pixel in metres: the file's own where it has one, else
  // the map must be the grid itself.
  double px = cell, py = cell;
  std::string what = std::string(format_name(format)) + " " + std::to_string(m.nx) + " x " +
                     std::to_string(m.ny) + " pixels";
  const bool georeferenced = m.pixel_w > 0 && m.pixel_h > 0;
  if (georeferenced) {
    const double to_m = m.units_m > 0 ? m.units_m : 1.0;
    px = m.pixel_w * to_m;
    py = m.pixel_h * to_m;
    what += " of " + num(m.pixel_w) + " x " + num(m.pixel_h) + " " + m.units +
            (m.units_m > 0 ? "" : " (no CRS: taken as metres)");
    const double ex = m.nx * px, ey = m.ny * py, dx = nx * cell, dy = ny * cell;
    if (std::fabs(ex - dx) > std::max(px, cell) + 1e-9 * dx ||
        std::fabs(ey - dy) > std::max(py, cell) + 1e-9 * dy)
      throw MapError(named + " covers " + num(ex) + " m x " + num(ey) + " m (" + what +
                     "); the domain is " + num(dx) + " m x " + num(dy) + " m (nx * cell_size_m x " +
                     "ny * cell_size_m); crop or warp the raster to the domain's extent");
  } else if (m.nx != nx || m.ny != ny) {
    throw MapError(named + " is " + std::to_string(m.nx) + " x " + std::to_string(m.ny) +
                   " cells; the domain is " + std::to_string(nx) + " x " + std::to_string(ny) +
                   " (nx x ny); a map without a pixel size must have the domain's size (a "
                   "GeoTIFF with a pixel size is resampled)");
  }

  // The torus joins opposite borders: a step there would be a cliff that
  // the simulation then erodes as if it were real.
  if (map.blend_border_m() > 0) {
    const int wx = static_cast<int>(std::lround(map.blend_border_m() / px));
    const int wy = static_cast<int>(std::lround(map.blend_border_m() / py));
    io::blend_borders(m, wx, wy);
    what += ", borders cross-faded over " + num(map.blend_border_m()) + " m";
  } else {
    const double range = io::range_of(m);
    const double tol = map.seam_tolerance();
    for (int axis = 0; axis < 2; ++axis) {
      const io::Seam s = io::seam_of(m, axis);
      if (s.jump > tol * range && s.jump > 4 * s.interior)
        throw MapError(named + " is not tileable: its " +
                       (axis == 0 ? "west and east borders" : "south and north borders") +
                       " differ by " + num(s.jump) + " on average, " + num(100 * s.jump / range) +
                       "% of its range " + num(range) + " (seam_tolerance " + num(100 * tol) +
                       "%); the domain is a torus, so set map.blend_border_m (metres) to "
                       "cross-fade the borders, or make the map tileable");
    }
  }
  if (m.nx != nx || m.ny != ny) {
    m = io::resample_periodic(m, nx, ny);
    what += ", resampled bilinearly (periodic) to " + std::to_string(nx) + " x " +
            std::to_string(ny) + " cells of " + num(cell) + " m";
  }
  if (note) *note = what;
  return m;
}

std::vector<std::string> describe_maps(const erg::v1::JobSpec& spec, const std::string& base_dir) {
  std::vector<std::string> out;
  const auto& L = spec.layers();
  const std::pair<const char*, const erg::v1::Layer*> layers[] = {{"bedrock", &L.bedrock()},
                                                                  {"sand", &L.sand()},
                                                                  {"vegetation", &L.vegetation()},
                                                                  {"resistance", &L.resistance()}};
  for (const auto& [name, layer] : layers) {
    if (!layer->has_map()) continue;
    std::string note;
    try {
      load_map(layer->map(), spec, base_dir, &note);
      out.push_back(std::string("layers.") + name + ".map: " + note);
    } catch (const std::exception& e) {
      out.push_back(std::string("layers.") + name + ".map" + e.what());
    }
  }
  return out;
}

}  // namespace erg::job
