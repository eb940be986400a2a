// SPDX-License-Identifier: Apache-2.0
// CF-1.10 / netCDF-4 metadata of snapshots (cf.h).
#include "io/cf.h"

#include <hdf5_hl.h>

#include <array>
#include <cstdint>
#include <vector>

#include "core/fields.h"
#include "io/atomic_file.h"
#include "io/hdf5_util.h"

namespace erg::io::detail {

// Creates a 1-D float64 dimension scale and writes its values and attributes.
void write_cf_coordinate(hid_t file, const CfCoordinate& c, const std::vector<double>& values,
                         hid_t dxpl, bool write_values, const std::string& path) {
  const std::string what = std::string("coordinate '") + c.name + "'";
  const hsize_t n = values.size();
  Hid space = checked(H5Screate_simple(1, &n, nullptr), H5Sclose, path, "dataspace for " + what);
  Hid dset = checked(
      H5Dcreate2(file, c.name, H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
      H5Dclose, path, "cannot create " + what);
  Hid mem = checked(H5Screate_simple(1, &n, nullptr), H5Sclose, path, "memory space for " + what);
  Hid file_space = checked(H5Dget_space(dset.get()), H5Sclose, path, "dataspace of " + what);
  if (!write_values) {
    check(H5Sselect_none(mem.get()), path, "H5Sselect_none");
    check(H5Sselect_none(file_space.get()), path, "H5Sselect_none");
  }
  static const double kNothing = 0;
  const void* buf = write_values ? static_cast<const void*>(values.data()) : &kNothing;
  check(H5Dwrite(dset.get(), H5T_NATIVE_DOUBLE, mem.get(), file_space.get(), dxpl, buf), path,
        "cannot write " + what);
  // The dimension's name is the dataset's: netCDF-4 then calls the dimension
  // and its coordinate variable both `c.name`.
  check(H5DSset_scale(dset.get(), c.name), path, "cannot make " + what + " a dimension scale");
  write_attr_str(dset.get(), "units", c.units, path);
  write_attr_str(dset.get(), "long_name", c.long_name, path);
  write_attr_str(dset.get(), "standard_name", c.standard_name, path);
  write_attr_str(dset.get(), "axis", c.axis, path);
  close_checked(dset, path, "cannot close " + what);
}

double snapshot_time_days(const SnapshotMeta& meta) {
  return meta.time_days;
}

void write_cf(hid_t file, const SnapshotMeta& meta, const std::vector<std::string>& layers,
              hid_t dxpl, bool write_values, const std::string& path) {
  std::vector<double> xs(static_cast<std::size_t>(meta.nx)), ys(static_cast<std::size_t>(meta.ny));
  for (std::size_t i = 0; i < xs.size(); ++i)
    xs[i] = (static_cast<double>(i) + 0.5) * meta.cell_size_m;
  for (std::size_t j = 0; j < ys.size(); ++j)
    ys[j] = (static_cast<double>(j) + 0.5) * meta.cell_size_m;
  // Elapsed simulated time: a run has no calendar date, so no "since". The
  // UDUNITS unit "day", not "days": xarray decodes "days" into timedelta64[ns],
  // which silently overflows past 292 years (a long dune run); "day" stays a
  // float number of days.
  write_cf_coordinate(file,
                      {"time", "simulated time since the start of the run", "day", "time", "T"},
                      {snapshot_time_days(meta)}, dxpl, write_values, path);
  write_cf_coordinate(
      file, {"y", "y (northward) of the cell centre", "m", "projection_y_coordinate", "Y"}, ys,
      dxpl, write_values, path);
  write_cf_coordinate(file,
                      {"x", "x (eastward) of the cell centre", "m", "projection_x_coordinate", "X"},
                      xs, dxpl, write_values, path);

  Hid time = checked(H5Dopen2(file, "time", H5P_DEFAULT), H5Dclose, path, "cannot open /time");
  Hid y = checked(H5Dopen2(file, "y", H5P_DEFAULT), H5Dclose, path, "cannot open /y");
  Hid x = checked(H5Dopen2(file, "x", H5P_DEFAULT), H5Dclose, path, "cannot open /x");
  for (const std::string& name : layers) {
    const std::string what = "dataset '" + name + "'";
    Hid dset =
        checked(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose, path, "cannot open " + what);
    check(H5DSattach_scale(dset.get(), time.get(), 0), path, "cannot attach /time to " + what);
    check(H5DSattach_scale(dset.get(), y.get(), 1), path, "cannot attach /y to " + what);
    check(H5DSattach_scale(dset.get(), x.get(), 2), path, "cannot attach /x to " + what);
    // The metadata of the registry (core/fields.h).
    if (const fields::Id id = fields::by_name(name); id != fields::kCount) {
      const fields::Info& f = fields::info(id);
      write_attr_str(dset.get(), "units", f.unit, path);
      write_attr_str(dset.get(), "long_name", f.snapshot.long_name, path);
      if (*f.snapshot.standard_name)
        write_attr_str(dset.get(), "standard_name", f.snapshot.standard_name, path);
    }
    close_checked(dset, path, "cannot close " + what);
  }
  close_checked(x, path, "cannot close /x");
  close_checked(y, path, "cannot close /y");
  close_checked(time, path, "cannot close /time");

  write_attr_str(file, "Conventions", "CF-1.10", path);
  write_attr_str(file, "title", "erg snapshot, step " + std::to_string(meta.step), path);
  write_attr_str(file, "source", "erg " + meta.erg_version + " (" + meta.backend + " backend)",
                 path);
}

}  // namespace erg::io::detail
