// SPDX-License-Identifier: Apache-2.0
// Measured wind records for `erg wind import` (README "Wind records"): an
// hourly CSV (time,u,v or time,speed,direction) or an ERA5 single-levels
// netCDF4 file (u10, v10, time or valid_time, latitude, longitude), read
// into wind vectors in erg's frame, and the sand rose of a record as a PNG.
//
// Directions: u and v are the components the wind blows towards (u east =
// +x, v north = +y), as in ERA5 and as erg's wind vector; a CSV `direction`
// is meteorological, the compass bearing (clockwise from north) the wind
// comes FROM, so u = -speed sin(direction), v = -speed cos(direction).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace erg::io {

struct WindRecord {
  std::vector<std::int64_t> time_s;  // seconds since 1970-01-01T00:00:00Z, increasing
  std::vector<double> u, v;          // m/s towards east (+x) and north (+y)
  std::string where;                 // the grid point read (netCDF), for reports
};

// Where to read an ERA5 file: the grid point nearest (lat, lon), or the
// point of indices (x = longitude index, y = latitude index).
struct GridPick {
  bool by_point = false;
  double lat = 0, lon = 0;
  bool by_index = false;
  long x = 0, y = 0;
};

// Both throw IoError "<path>: <what>" naming the line/field and the allowed
// values; nothing is returned for a record with any bad row.
WindRecord read_wind_csv(const std::string& path);
WindRecord read_wind_era5(const std::string& path, const GridPick& pick);

// "YYYY-MM-DDTHH:MM[:SS][Z|+00:00]" (a space for T allowed) to seconds since
// the epoch; false when it does not parse.
bool parse_iso8601(const std::string& text, std::int64_t& seconds);
std::string format_iso8601(std::int64_t seconds);

// The sand rose (Fryberger & Dean 1979): one petal per direction sector,
// sector k centred on the compass bearing k * 360 / n the wind comes FROM,
// its length proportional to drift[k] (the longest reaching the edge), a
// north marker at the top, and the resultant drift as a blue line from the
// centre towards the compass bearing `rdd_bearing_deg` (where the sand
// goes), its length `rdp_over_dp` of the edge. `size` x `size` RGB,
// written atomically.
void write_sand_rose_png(const std::string& path, const std::vector<double>& drift,
                         double rdd_bearing_deg, double rdp_over_dp, int size);

}  // namespace erg::io
