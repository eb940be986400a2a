// SPDX-License-Identifier: Apache-2.0
#include "io/wind_record.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include "io/hdf5_util.h"
#include "io/png_util.h"

namespace erg::io {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Days from 1970-01-01 of a proleptic Gregorian date (Hinnant's
// days_from_civil), so times need no time zone database.
std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

std::string trim(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool parse_number(const std::string& text, double& v) {
  const std::string t = trim(text);
  if (t.empty()) return false;
  char* end = nullptr;
  v = std::strtod(t.c_str(), &end);
  return end == t.c_str() + t.size() && std::isfinite(v);
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) out.push_back(trim(cell));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

}  // namespace

bool parse_iso8601(const std::string& text, std::int64_t& seconds) {
  const std::string t = trim(text);
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, n = 0;
  double sec = 0;
  if (std::sscanf(t.c_str(), "%4d-%2d-%2d%n", &y, &mo, &d, &n) != 3 || n != 10) return false;
  std::size_t pos = 10;
  if (pos < t.size() && (t[pos] == 'T' || t[pos] == ' ')) {
    int m = 0;
    if (std::sscanf(t.c_str() + pos + 1, "%2d:%2d%n", &h, &mi, &m) != 2 || m != 5) return false;
    pos += 1 + 5;
    if (pos < t.size() && t[pos] == ':') {
      char* end = nullptr;
      sec = std::strtod(t.c_str() + pos + 1, &end);
      if (end == t.c_str() + pos + 1) return false;
      pos = static_cast<std::size_t>(end - t.c_str());
    }
  }
  const std::string zone = t.substr(pos);
  if (!(zone.empty() || zone == "Z" || zone == "+00:00" || zone == " UTC")) return false;
  if (mo < 1 || mo > 12 || d < 1 || d > 31 || h > 23 || mi > 59 || !(sec >= 0 && sec < 61))
    return false;
  seconds = days_from_civil(y, static_cast<unsigned>(mo), static_cast<unsigned>(d)) * 86400 +
            h * 3600 + mi * 60 + static_cast<std::int64_t>(std::llround(sec));
  return true;
}

std::string format_iso8601(std::int64_t seconds) {
  // civil_from_days (Hinnant), the inverse of days_from_civil.
  std::int64_t z = (seconds >= 0 ? seconds : seconds - 86399) / 86400;
  const int rem = static_cast<int>(seconds - z * 86400);  // [0, 86400)
  z += 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const unsigned doe = static_cast<unsigned>(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  const unsigned d = doy - (153 * mp + 2) / 5 + 1;
  const unsigned m = mp < 10 ? mp + 3 : mp - 9;
  const std::int64_t y = static_cast<std::int64_t>(yoe) + era * 400 + (m <= 2);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04lld-%02u-%02uT%02d:%02d:%02dZ", static_cast<long long>(y), m,
                d, rem / 3600, rem / 60 % 60, rem % 60);
  return buf;
}

WindRecord read_wind_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) detail::fail_errno(path, "cannot open wind record", errno);
  std::string line;
  if (!std::getline(in, line)) detail::fail(path, "empty file: expected a header row");
  std::vector<std::string> header = split_csv(line);
  for (auto& h : header) h = lower(h);
  auto column = [&](const std::string& name) {
    auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  };
  const int ct = column("time"), cu = column("u"), cv = column("v"), cs = column("speed"),
            cd = column("direction");
  const bool uv = cu >= 0 && cv >= 0;
  if (ct < 0 || (!uv && (cs < 0 || cd < 0)))
    detail::fail(path, "line 1: header '" + trim(line) +
                           "' lacks the columns: need time,u,v (m/s towards east and north) or "
                           "time,speed,direction (m/s; degrees clockwise from north, from)");
  WindRecord r;
  int lineno = 1;
  while (std::getline(in, line)) {
    ++lineno;
    if (trim(line).empty()) continue;
    const std::vector<std::string> cells = split_csv(line);
    const std::string at = "line " + std::to_string(lineno) + ": ";
    if (cells.size() != header.size())
      detail::fail(path, at + std::to_string(cells.size()) + " fields, the header has " +
                             std::to_string(header.size()));
    std::int64_t t = 0;
    if (!parse_iso8601(cells[ct], t))
      detail::fail(path, at + "time '" + cells[ct] +
                             "' is not an ISO 8601 UTC time (YYYY-MM-DDTHH:MM[:SS][Z])");
    if (!r.time_s.empty() && t <= r.time_s.back())
      detail::fail(path, at + "time " + cells[ct] + " is not after the previous row's " +
                             format_iso8601(r.time_s.back()));
    auto number = [&](int c, const char* name, double lo, double hi) {
      double v = 0;
      if (!parse_number(cells[c], v))
        detail::fail(path, at + name + " '" + cells[c] + "' is not a number");
      if (v < lo || v > hi) {
        std::ostringstream o;
        o << at << name << " = " << v << " is outside [" << lo << ", " << hi << "]";
        detail::fail(path, o.str());
      }
      return v;
    };
    double u = 0, v = 0;
    if (uv) {
      u = number(cu, "u", -100, 100);
      v = number(cv, "v", -100, 100);
    } else {
      const double s = number(cs, "speed", 0, 100), d = number(cd, "direction", 0, 360);
      u = -s * std::sin(d * kPi / 180);
      v = -s * std::cos(d * kPi / 180);
    }
    r.time_s.push_back(t);
    r.u.push_back(u);
    r.v.push_back(v);
  }
  if (r.time_s.empty()) detail::fail(path, "no data rows after the header");
  return r;
}

namespace {

// A numeric 1-D coordinate variable of an ERA5 file.
std::vector<double> read_coordinate(hid_t file, const std::string& name, const std::string& path) {
  std::vector<hsize_t> dims;
  { detail::Hid d = detail::open_dataset(file, name, dims, path); }
  if (dims.size() != 1 || dims[0] == 0)
    detail::fail(path, "variable '" + name + "' has shape " + detail::shape_text(dims) +
                           ", expected one non-empty dimension");
  return detail::read_dataset<double>(file, name, H5T_NATIVE_DOUBLE, dims, path);
}

bool has_attr(hid_t obj, const char* name) {
  return H5Aexists(obj, name) > 0;
}

// Seconds of one unit of "<unit> since <date>" (CF time units).
double unit_seconds(const std::string& unit) {
  if (unit == "seconds" || unit == "second" || unit == "s") return 1;
  if (unit == "minutes" || unit == "minute") return 60;
  if (unit == "hours" || unit == "hour" || unit == "h") return 3600;
  if (unit == "days" || unit == "day" || unit == "d") return 86400;
  return 0;
}

}  // namespace

WindRecord read_wind_era5(const std::string& path, const GridPick& pick) {
  {
    // Older CDS downloads are netCDF-3 (classic), which is not HDF5.
    std::ifstream in(path, std::ios::binary);
    char magic[4] = {};
    if (in.read(magic, 4) && magic[0] == 'C' && magic[1] == 'D' && magic[2] == 'F')
      detail::fail(path,
                   "a netCDF-3 (classic) file; erg reads netCDF-4 (HDF5): convert it with "
                   "`nccopy -k nc4 FILE FILE4.nc`");
  }
  detail::Hdf5Guard guard;
  detail::Hid file = detail::open_hdf5_readonly(path, "ERA5 netCDF file");
  const hid_t f = file.get();
  // Newer ERA5 files (the CDS since 2024) name the time axis valid_time.
  const std::string tname = detail::link_exists(f, "valid_time") ? "valid_time" : "time";
  if (!detail::link_exists(f, tname))
    detail::fail(path, "no time variable: expected 'valid_time' or 'time' (ERA5 single levels)");
  const std::vector<double> tv = read_coordinate(f, tname, path);
  const std::vector<double> lat = read_coordinate(f, "latitude", path);
  const std::vector<double> lon = read_coordinate(f, "longitude", path);

  // Time: "<unit> since <date>" (CF).
  WindRecord r;
  {
    std::vector<hsize_t> dims;
    detail::Hid d = detail::open_dataset(f, tname, dims, path);
    const std::string units = detail::read_attr_str(d.get(), "units", path);
    const std::size_t since = units.find(" since ");
    const double us = since == std::string::npos ? 0 : unit_seconds(lower(units.substr(0, since)));
    std::int64_t epoch = 0;
    if (us == 0 || !parse_iso8601(units.substr(since + 7), epoch))
      detail::fail(path,
                   "variable '" + tname + "': units '" + units +
                       "' are not '<seconds|minutes|hours|days> since YYYY-MM-DD[ HH:MM:SS]'");
    for (std::size_t k = 0; k < tv.size(); ++k) {
      const std::int64_t t = epoch + static_cast<std::int64_t>(std::llround(tv[k] * us));
      if (k > 0 && t <= r.time_s.back())
        detail::fail(path, "variable '" + tname + "'[" + std::to_string(k) +
                               "] is not after the previous time");
      r.time_s.push_back(t);
    }
  }

  // The grid point: nearest (lat, lon), or indices.
  std::size_t ix = 0, iy = 0;
  if (pick.by_index) {
    if (pick.x < 0 || pick.x >= static_cast<long>(lon.size()) || pick.y < 0 ||
        pick.y >= static_cast<long>(lat.size()))
      detail::fail(path, "--x " + std::to_string(pick.x) + " --y " + std::to_string(pick.y) +
                             " is outside the grid: --x in [0, " + std::to_string(lon.size() - 1) +
                             "] (longitude), --y in [0, " + std::to_string(lat.size() - 1) +
                             "] (latitude)");
    ix = static_cast<std::size_t>(pick.x);
    iy = static_cast<std::size_t>(pick.y);
  } else if (pick.by_point) {
    // Half a grid spacing beyond the outermost points still has a nearest
    // point; ERA5's spacing is 0.25 degrees when the file has one point.
    auto spacing = [](const std::vector<double>& c) {
      return c.size() > 1 ? std::abs(c[1] - c[0]) : 0.25;
    };
    auto lon_diff = [](double a, double b) { return std::abs(std::remainder(a - b, 360.0)); };
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < lat.size(); ++k)
      if (std::abs(lat[k] - pick.lat) < best) best = std::abs(lat[k] - pick.lat), iy = k;
    const bool lat_out = best > spacing(lat) / 2 + 1e-9;
    best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < lon.size(); ++k)
      if (lon_diff(lon[k], pick.lon) < best) best = lon_diff(lon[k], pick.lon), ix = k;
    if (lat_out || best > spacing(lon) / 2 + 1e-9) {
      const auto [la0, la1] = std::minmax_element(lat.begin(), lat.end());
      const auto [lo0, lo1] = std::minmax_element(lon.begin(), lon.end());
      std::ostringstream o;
      o << "--point " << pick.lat << "," << pick.lon << " is outside the grid: latitude in ["
        << *la0 << ", " << *la1 << "], longitude in [" << *lo0 << ", " << *lo1
        << "] (to half a grid spacing)";
      detail::fail(path, o.str());
    }
  } else if (lat.size() > 1 || lon.size() > 1) {
    detail::fail(path, "the file has " + std::to_string(lat.size()) + " x " +
                           std::to_string(lon.size()) +
                           " grid points: choose one with --point LAT,LON or --x I --y J");
  }
  {
    std::ostringstream o;
    o << "latitude " << lat[iy] << ", longitude " << lon[ix] << " (--x " << ix << " --y " << iy
      << ")";
    r.where = o.str();
  }

  // u10 and v10 at the point: a hyperslab, so a year of a continent is not
  // read whole; unpacked with scale_factor and add_offset (CF), fill values
  // refused.
  auto component = [&](const std::string& name) {
    std::vector<hsize_t> dims;
    detail::Hid d = detail::open_dataset(f, name, dims, path);
    const std::vector<hsize_t> want = {tv.size(), lat.size(), lon.size()};
    if (dims != want)
      detail::fail(path, "variable '" + name + "' has shape " + detail::shape_text(dims) +
                             ", expected " + detail::shape_text(want) + " (" + tname +
                             ", latitude, longitude)");
    detail::Hid space =
        detail::checked(H5Dget_space(d.get()), H5Sclose, path, "dataspace of '" + name + "'");
    const hsize_t start[3] = {0, iy, ix}, count[3] = {tv.size(), 1, 1};
    detail::check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr),
                  path, "select the point in '" + name + "'");
    const hsize_t n = tv.size();
    detail::Hid mem = detail::checked(H5Screate_simple(1, &n, nullptr), H5Sclose, path, "memspace");
    std::vector<double> raw(tv.size());
    detail::check(
        H5Dread(d.get(), H5T_NATIVE_DOUBLE, mem.get(), space.get(), H5P_DEFAULT, raw.data()), path,
        "cannot read variable '" + name + "'");
    const double scale = has_attr(d.get(), "scale_factor")
                             ? detail::read_attr_f64(d.get(), "scale_factor", path)
                             : 1;
    const double offset =
        has_attr(d.get(), "add_offset") ? detail::read_attr_f64(d.get(), "add_offset", path) : 0;
    std::vector<double> fills;
    for (const char* a : {"_FillValue", "missing_value"})
      if (has_attr(d.get(), a)) fills.push_back(detail::read_attr_f64(d.get(), a, path));
    for (std::size_t k = 0; k < raw.size(); ++k) {
      const bool missing =
          !std::isfinite(raw[k]) || std::find(fills.begin(), fills.end(), raw[k]) != fills.end();
      const double value = raw[k] * scale + offset;
      if (missing || std::abs(value) > 100) {
        std::ostringstream o;
        o << "variable '" << name << "' at " << format_iso8601(r.time_s[k]) << " (" << tname << "["
          << k << "]), " << r.where << ": "
          << (missing ? std::string("missing value") : std::to_string(value) + " m/s")
          << "; allowed: a wind component in [-100, 100] m/s";
        detail::fail(path, o.str());
      }
      raw[k] = value;
    }
    return raw;
  };
  r.u = component("u10");
  r.v = component("v10");
  return r;
}

void write_sand_rose_png(const std::string& path, const std::vector<double>& drift,
                         double rdd_bearing_deg, double rdp_over_dp, int size) {
  const int n = static_cast<int>(drift.size());
  const double top = n ? *std::max_element(drift.begin(), drift.end()) : 0;
  const double c = (size - 1) / 2.0, reach = 0.42 * size, sector = 360.0 / std::max(n, 1);
  std::vector<unsigned char> image(static_cast<std::size_t>(size) * size * 3, 255);
  for (int py = 0; py < size; ++py)
    for (int px = 0; px < size; ++px) {
      unsigned char* p = &image[(static_cast<std::size_t>(py) * size + px) * 3];
      const double dx = px - c, dy = c - py, r = std::hypot(dx, dy);
      // Compass bearing of the pixel, clockwise from north (up).
      double bearing = std::atan2(dx, dy) * 180 / kPi;
      if (bearing < 0) bearing += 360;
      const int k = static_cast<int>(std::lround(bearing / sector)) % std::max(n, 1);
      const double off = std::abs(std::remainder(bearing - k * sector, 360.0));
      auto set = [&](int R, int G, int B) {
        p[0] = static_cast<unsigned char>(R);
        p[1] = static_cast<unsigned char>(G);
        p[2] = static_cast<unsigned char>(B);
      };
      if (std::abs(r - reach) < 0.75) set(160, 160, 160);  // the full-length circle
      if (n && top > 0 && off <= 0.4 * sector && r <= reach * drift[k] / top) set(196, 128, 56);
      // North marker: a black triangle above the circle, pointing up.
      const double h = 0.06 * size;
      if (py < h && std::abs(dx) <= (py + 1) * 0.4) set(0, 0, 0);
      // The resultant: within 1.5 pixels of the segment from the centre.
      const double ex = std::sin(rdd_bearing_deg * kPi / 180),
                   ey = std::cos(rdd_bearing_deg * kPi / 180);
      const double along = dx * ex + dy * ey;
      if (along >= 0 && along <= reach * rdp_over_dp && std::abs(dx * ey - dy * ex) <= 1.5)
        set(40, 70, 160);
    }
  detail::write_png_atomically(
      path, size, size, 8, PNG_COLOR_TYPE_RGB, 3, [&](int row, unsigned char* out) {
        std::copy_n(&image[static_cast<std::size_t>(row) * size * 3], size * 3, out);
      });
}

}  // namespace erg::io
