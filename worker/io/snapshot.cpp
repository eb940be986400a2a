// SPDX-License-Identifier: Apache-2.0
// Snapshots: one HDF5 file per output step (float32 layers in metres plus the
// run's metadata as root attributes), a netCDF-4 file with CF metadata
// (cf.cpp); the XDMF sidecars for ParaView are in xdmf.cpp. The file contract
// is documented in README.md; keep the two in step.
#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "io/atomic_file.h"
#include "io/cf.h"
#include "io/formats.h"
#include "io/hdf5_util.h"
#include "io/io.h"

namespace erg::io {

// ---- shared with the parallel writer (formats.h) ------------------------------

void detail::check_grid(const std::string& path, int nx, int ny) {
  if (nx <= 0 || ny <= 0) {
    fail(path, "invalid grid " + std::to_string(nx) + " x " + std::to_string(ny) +
                   " (nx and ny must be positive)");
  }
}

std::vector<fields::Id> snapshot_layer_ids(const SnapshotFields& f) {
  std::vector<fields::Id> ids;
  for (const fields::Id id : fields::snapshot_order())
    if (f[id].data) ids.push_back(id);
  return ids;
}

std::vector<detail::SnapshotLayer> detail::snapshot_layers(const SnapshotFields& f,
                                                           const std::vector<fields::Id>& ids) {
  std::vector<SnapshotLayer> layers;
  for (const fields::Id id : ids)
    layers.push_back({fields::info(id).name, f[id].data, f[id].stride, f[id].offset});
  return layers;
}

void detail::check_required_layers(const std::string& path, const SnapshotFields& f,
                                   const std::string& where) {
  std::string required, missing;
  for (const fields::Id id : fields::snapshot_order()) {
    if (fields::info(id).snapshot.optional) continue;
    required += std::string(required.empty() ? "" : ", ") + fields::info(id).name;
    if (!f[id].data) missing += std::string(missing.empty() ? "" : ", ") + fields::info(id).name;
  }
  if (!missing.empty())
    fail(path, "snapshot needs the layers " + required + " (got a null pointer for " + missing +
                   where + ")");
}

detail::Hid detail::layer_memory_space(const SnapshotLayer& l, std::size_t cells,
                                       const std::string& path) {
  const hsize_t n = static_cast<hsize_t>(cells) * static_cast<hsize_t>(l.stride);
  Hid mem = checked(H5Screate_simple(1, &n, nullptr), H5Sclose, path,
                    std::string("memory dataspace for '") + l.name + "'");
  const hsize_t start = static_cast<hsize_t>(l.offset), stride = static_cast<hsize_t>(l.stride),
                count = static_cast<hsize_t>(cells);
  check(H5Sselect_hyperslab(mem.get(), H5S_SELECT_SET, &start, &stride, &count, nullptr), path,
        std::string("cannot select the values of '") + l.name + "'");
  return mem;
}

void detail::write_snapshot_attrs(hid_t fid, const SnapshotMeta& meta, const std::string& path) {
  write_attr_i64(fid, "step", meta.step, path);
  write_attr_f64(fid, "time_days", meta.time_days, path);
  write_attr_f64(fid, "cell_size_m", meta.cell_size_m, path);
  write_attr_i64(fid, "nx", meta.nx, path);
  write_attr_i64(fid, "ny", meta.ny, path);
  write_attr_str(fid, "job_spec", meta.job_spec_json, path);
  write_attr_str(fid, "erg_version", meta.erg_version, path);
  write_attr_f64(fid, "unit_m", meta.unit_m, path);
  write_attr_str(fid, "sand_units_total", meta.sand_units_total, path);
  write_attr_str(fid, "bedrock_units_total", meta.bedrock_units_total, path);
  write_attr_str(fid, "airborne_units_total", meta.airborne_units_total, path);
  write_attr_u64(fid, "seed", meta.seed, path);
  write_attr_str(fid, "backend", meta.backend, path);
  // Fixed by the model: the domain is a torus and all lengths are metres.
  write_attr_str(fid, "periodic", "xy", path);
  write_attr_str(fid, "units", "m", path);
  if (std::isfinite(meta.ground_min_m) && std::isfinite(meta.ground_max_m)) {
    write_attr_f64(fid, "ground_min_m", meta.ground_min_m, path);
    write_attr_f64(fid, "ground_max_m", meta.ground_max_m, path);
  }
  write_physical_attrs(fid, meta, path);
}

// Time in seconds and Julian years (365.25 days), the wind of the step and
// how the time per step was obtained (sim/calibration.h).
void detail::write_physical_attrs(hid_t fid, const SnapshotMeta& meta, const std::string& path) {
  write_attr_f64(fid, "time_s", meta.time_s, path);
  write_attr_f64(fid, "time_years", meta.time_s / (365.25 * 86400.0), path);
  write_attr_str(fid, "wind_units", meta.physical ? "physical" : "model", path);
  write_attr_f64(fid, "wind_speed_mps", meta.wind_speed_mps, path);
  write_attr_f64(fid, "wind_direction_deg", meta.wind_direction_deg, path);
  write_attr_f64(fid, "time_step_s", meta.dt_s, path);
  if (!meta.physical) {
    write_attr_str(fid, "time_step_source", "model.time_step_days (a label)", path);
    return;
  }
  write_attr_str(fid, "time_step_source",
                 "measured flat-bed flux / flux law at the reference u* (docs/physical-units.md)",
                 path);
  write_attr_f64(fid, "shear_velocity_mps", meta.shear_velocity_mps, path);
  write_attr_f64(fid, "threshold_shear_velocity_mps", meta.threshold_mps, path);
  write_attr_f64(fid, "calibration_shear_velocity_mps", meta.reference_shear_velocity_mps, path);
  write_attr_f64(fid, "calibration_model_flux_m2_per_step", meta.calibration_flux_m2_per_step,
                 path);
  write_attr_f64(fid, "calibration_law_flux_m2_per_s", meta.calibration_law_flux_m2_per_s, path);
  write_attr_str(fid, "flux_law", meta.flux_law, path);
}

namespace {

using detail::AtomicFile;
using detail::check_grid;
using detail::fail;
using detail::Hid;

// Writes one layer as /<name> [1][ny][nx], chunks of at most 1 x 256 x 256.
void write_layer(hid_t fid, const detail::SnapshotLayer& l, hsize_t ny, hsize_t nx,
                 const std::string& path) {
  const std::string what = std::string("dataset '") + l.name + "'";
  const std::vector<hsize_t> dims = {1, ny, nx};
  Hid space = detail::checked(H5Screate_simple(3, dims.data(), nullptr), H5Sclose, path,
                              "dataspace for " + what);
  Hid dcpl = detail::deflate_dcpl({1, std::min<hsize_t>(ny, 256), std::min<hsize_t>(nx, 256)},
                                  detail::kSnapshotDeflate, path);
  Hid dset = detail::checked(
      H5Dcreate2(fid, l.name, H5T_IEEE_F32LE, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
      H5Dclose, path, "cannot create " + what);
  Hid mem = detail::layer_memory_space(l, static_cast<std::size_t>(ny * nx), path);
  detail::check(H5Dwrite(dset.get(), H5T_NATIVE_FLOAT, mem.get(), H5S_ALL, H5P_DEFAULT, l.data),
                path, "cannot write " + what);
  detail::close_checked(dset, path, "cannot close " + what);
}

// Reads a layer written as [1][ny][nx] or, by erg before the CF layout, as
// [ny][nx].
std::vector<float> read_layer(hid_t fid, const char* name, hsize_t ny, hsize_t nx,
                              const std::string& path) {
  std::vector<hsize_t> dims;
  Hid dset = detail::open_dataset(fid, name, dims, path);
  const std::vector<hsize_t> want = {1, ny, nx}, old = {ny, nx};
  if (dims != want && dims != old) {
    fail(path, std::string("dataset '") + name + "' has shape " + detail::shape_text(dims) +
                   ", expected " + detail::shape_text(want));
  }
  std::vector<float> values(static_cast<std::size_t>(ny * nx));
  detail::check(H5Dread(dset.get(), H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
                path, std::string("cannot read dataset '") + name + "' (corrupt?)");
  return values;
}

// Reads nx or ny back, rejecting values that do not fit the int of the API.
int read_extent(hid_t file, const char* name, const std::string& path) {
  std::int64_t v = detail::read_attr_i64(file, name, path);
  if (v <= 0 || v > INT_MAX) {
    fail(path, std::string("attribute '") + name + "' = " + std::to_string(v) + " is out of range");
  }
  return static_cast<int>(v);
}

}  // namespace

void write_snapshot(const std::string& path, const SnapshotMeta& meta, const SnapshotFields& f,
                    const OverviewPyramid* pyramid) {
  // Argument errors first, before anything touches the disk.
  check_grid(path, meta.nx, meta.ny);
  detail::check_required_layers(path, f);

  AtomicFile out(path);
  std::vector<char> image;
  {
    detail::Hdf5Guard guard;
    Hid file = detail::create_hdf5_in_memory(out);
    const hid_t fid = file.get();
    const hsize_t ny = static_cast<hsize_t>(meta.ny), nx = static_cast<hsize_t>(meta.nx);
    std::vector<std::string> names;
    for (const detail::SnapshotLayer& l : detail::snapshot_layers(f, snapshot_layer_ids(f))) {
      write_layer(fid, l, ny, nx, path);
      names.emplace_back(l.name);
    }
    detail::write_snapshot_attrs(fid, meta, path);
    detail::write_cf(fid, meta, names, H5P_DEFAULT, /*write_values=*/true, path);
    if (pyramid) detail::write_overview(fid, meta, *pyramid, H5P_DEFAULT, true, path);

    image = detail::take_hdf5_image(file, path);
  }
  out.write_whole(image.data(), image.size());
  out.commit();
}

namespace {
// The root attributes of an open snapshot.
SnapshotMeta read_meta(hid_t fid, const std::string& path) {
  SnapshotMeta m;
  m.nx = read_extent(fid, "nx", path);
  m.ny = read_extent(fid, "ny", path);
  m.step = detail::read_attr_i64(fid, "step", path);
  m.time_days = detail::read_attr_f64(fid, "time_days", path);
  m.cell_size_m = detail::read_attr_f64(fid, "cell_size_m", path);
  m.job_spec_json = detail::read_attr_str(fid, "job_spec", path);
  m.erg_version = detail::read_attr_str(fid, "erg_version", path);
  m.unit_m = detail::read_attr_f64(fid, "unit_m", path);
  m.sand_units_total = detail::read_attr_str(fid, "sand_units_total", path);
  m.bedrock_units_total = detail::read_attr_str(fid, "bedrock_units_total", path);
  m.airborne_units_total = detail::read_attr_str(fid, "airborne_units_total", path);
  m.seed = detail::read_attr_u64(fid, "seed", path);
  m.backend = detail::read_attr_str(fid, "backend", path);
  if (H5Aexists(fid, "time_s") > 0) m.time_s = detail::read_attr_f64(fid, "time_s", path);
  if (H5Aexists(fid, "ground_min_m") > 0 && H5Aexists(fid, "ground_max_m") > 0) {
    m.ground_min_m = detail::read_attr_f64(fid, "ground_min_m", path);
    m.ground_max_m = detail::read_attr_f64(fid, "ground_max_m", path);
  }
  return m;
}
}  // namespace

SnapshotMeta read_snapshot_meta(const std::string& path) {
  detail::Hdf5Guard guard;
  Hid file = detail::open_hdf5_readonly(path, "snapshot");
  return read_meta(file.get(), path);
}

Snapshot read_snapshot(const std::string& path, bool terrain_only) {
  detail::Hdf5Guard guard;
  Hid file = detail::open_hdf5_readonly(path, "snapshot");
  const hid_t fid = file.get();

  Snapshot s;
  SnapshotMeta& m = s.meta;
  m = read_meta(fid, path);

  const hsize_t ny = static_cast<hsize_t>(m.ny), nx = static_cast<hsize_t>(m.nx);
  auto layer = [&](fields::Id id) { s[id] = read_layer(fid, fields::info(id).name, ny, nx, path); };
  // The terrain (what a preview needs), then the rest.
  for (const fields::Id id : {fields::kBedrock, fields::kSand, fields::kVegetation}) layer(id);
  if (terrain_only) return s;
  if (!detail::link_exists(fid, "wind_x") && detail::link_exists(fid, "wind")) {
    // Files written before the CF layout: one interleaved [ny][nx][2] /wind.
    s.wind = detail::read_dataset<float>(fid, "wind", H5T_NATIVE_FLOAT, {ny, nx, 2}, path);
    s[fields::kWindX].resize(s.wind.size() / 2);
    s[fields::kWindY].resize(s.wind.size() / 2);
    for (std::size_t c = 0; c < s.wind.size() / 2; ++c) {
      s[fields::kWindX][c] = s.wind[2 * c];
      s[fields::kWindY][c] = s.wind[2 * c + 1];
    }
  }
  for (const fields::Id id : fields::snapshot_order()) {
    if (!s[id].empty()) continue;  // read above
    if (fields::info(id).snapshot.optional && !detail::link_exists(fid, fields::info(id).name))
      continue;
    layer(id);
  }
  if (s.wind.empty()) {
    const std::vector<float>&wx = s[fields::kWindX], &wy = s[fields::kWindY];
    s.wind.resize(2 * wx.size());
    for (std::size_t c = 0; c < wx.size(); ++c) {
      s.wind[2 * c] = wx[c];
      s.wind[2 * c + 1] = wy[c];
    }
  }
  return s;
}

}  // namespace erg::io
