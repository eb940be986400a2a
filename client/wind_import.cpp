// SPDX-License-Identifier: Apache-2.0
// erg wind import FILE: a measured wind record (an hourly CSV, or an ERA5
// single-levels netCDF file; io/wind_record.h) turned into a job's wind:
// a wind.series, or with --rose a wind.rose, in WIND_AT_HEIGHT units (the
// record's height and the bed's roughness go with it, so the worker turns
// the speeds into u* by the law of the wall). Prints the record's rose and
// its drift potentials (Fryberger & Dean 1979 with the job's flux law,
// physics::drift_potential, the same numbers as erg calibrate's law_*) and
// draws the sand rose as a PNG. README "Wind records".
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "io/atomic_file.h"
#include "io/wind_record.h"
#include "job/spec.h"
#include "sim/calibration.h"
#include "wind/physics.h"

namespace erg::client {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kSecondsPerYear = 3.15576e7;  // Julian year, as the snapshots' time_years

struct ImportArgs {
  std::string file, format, job, out, png = "wind_rose.png";
  io::GridPick pick;
  // Absent: the proto's defaults for WindRegime (10 m; 0, meaning d/30).
  std::optional<double> height_m, roughness_m;
  double step_hours = 0, speed_bin_mps = 1;
  int sectors = 16;
  bool rose = false;
};

double number_arg(const std::string& flag, const std::string& text, double lo, double hi) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || !(v >= lo && v <= hi)) {
    std::ostringstream o;
    o << flag << " '" << text << "' must be a number in [" << lo << ", " << hi << "]";
    throw std::invalid_argument(o.str());
  }
  return v;
}

ImportArgs parse_import_args(const std::vector<std::string>& args) {
  ImportArgs a;
  bool x = false, y = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& f = args[i];
    const bool has_value = i + 1 < args.size();
    if (f == "--rose") {
      a.rose = true;
    } else if (!has_value && f.size() > 2 && f.compare(0, 2, "--") == 0) {
      throw std::invalid_argument(f + " needs a value");
    } else if (f == "--format") {
      a.format = args[++i];
      if (a.format != "csv" && a.format != "netcdf")
        throw std::invalid_argument("--format '" + a.format + "' must be csv or netcdf");
    } else if (f == "--point") {
      const std::string v = args[++i];
      const std::size_t comma = v.find(',');
      if (comma == std::string::npos)
        throw std::invalid_argument("--point '" + v + "' must be LAT,LON in degrees");
      a.pick.by_point = true;
      a.pick.lat = number_arg("--point latitude", v.substr(0, comma), -90, 90);
      a.pick.lon = number_arg("--point longitude", v.substr(comma + 1), -360, 360);
    } else if (f == "--x" || f == "--y") {
      const double v = number_arg(f, args[++i], 0, 1e9);
      if (v != std::floor(v)) throw std::invalid_argument(f + " must be a grid index");
      a.pick.by_index = true;
      (f == "--x" ? a.pick.x : a.pick.y) = static_cast<long>(v);
      (f == "--x" ? x : y) = true;
    } else if (f == "--height") {
      a.height_m = number_arg(f, args[++i], 0.01, 1000);
    } else if (f == "--roughness") {
      a.roughness_m = number_arg(f, args[++i], 0, 1);
    } else if (f == "--step-hours") {
      a.step_hours = number_arg(f, args[++i], 1e-3, 1e6);
    } else if (f == "--sectors") {
      a.sectors = static_cast<int>(number_arg(f, args[++i], 4, 72));
    } else if (f == "--speed-bin") {
      a.speed_bin_mps = number_arg(f, args[++i], 0.1, 100);
    } else if (f == "--job") {
      a.job = args[++i];
    } else if (f == "--out") {
      a.out = args[++i];
    } else if (f == "--png") {
      a.png = args[++i];
    } else if (a.file.empty() && !f.empty() && f[0] != '-') {
      a.file = f;
    } else {
      throw std::invalid_argument("unexpected argument '" + f + "'");
    }
  }
  if (a.file.empty()) throw std::invalid_argument("FILE is required");
  if (a.format.empty()) throw std::invalid_argument("--format csv|netcdf is required");
  if (a.pick.by_point && a.pick.by_index)
    throw std::invalid_argument("--point and --x/--y both given: choose one");
  if (a.pick.by_index && !(x && y)) throw std::invalid_argument("--x and --y go together");
  if ((a.pick.by_point || a.pick.by_index) && a.format != "netcdf")
    throw std::invalid_argument("--point and --x/--y choose a grid point of a netCDF file");
  return a;
}

// erg's direction of a wind vector: towards, degrees ccw from +x (east).
double erg_direction(double u, double v) {
  return std::atan2(v, u) * 180 / kPi;
}
// Compass bearing the wind comes FROM, [0, 360).
double bearing_from(double u, double v) {
  double b = std::atan2(-u, -v) * 180 / kPi;
  return b < 0 ? b + 360 : b;
}

// Six decimals: finer than any anemometer, and no 1e-14 of rounding noise
// (or -0) in the job.
double tidy(double v) {
  return std::round(v * 1e6) / 1e6 + 0.0;
}

const char* compass_name(int k, int n) {
  static const char* k16[] = {"N", "NNE", "NE", "ENE", "E", "ESE", "SE", "SSE",
                              "S", "SSW", "SW", "WSW", "W", "WNW", "NW", "NNW"};
  if (n == 16) return k16[k];
  if (n == 8) return k16[2 * k];
  if (n == 4) return k16[4 * k];
  return "";
}

}  // namespace

int cmd_wind(const std::vector<std::string>& all) {
  ImportArgs a;
  try {
    if (all.empty() || all[0] != "import")
      throw std::invalid_argument("unknown or missing subcommand (erg wind import)");
    a = parse_import_args({all.begin() + 1, all.end()});
  } catch (const std::exception& e) {
    std::cerr << "erg wind import: " << e.what() << "\nusage:\n" << usage_of("wind");
    return 2;
  }
  try {
    io::WindRecord rec =
        a.format == "csv" ? io::read_wind_csv(a.file) : io::read_wind_era5(a.file, a.pick);
    const std::size_t n = rec.time_s.size();
    for (std::size_t k = 0; k < n; ++k)
      if (std::hypot(rec.u[k], rec.v[k]) > 100)
        throw std::runtime_error(a.file + ": the wind at " + io::format_iso8601(rec.time_s[k]) +
                                 " is " + std::to_string(std::hypot(rec.u[k], rec.v[k])) +
                                 " m/s; allowed: speeds in [0, 100] m/s");

    // The job the wind goes into: its sand and flux law, and its calibrated
    // step (which turns record hours into steps); else the default sand.
    erg::v1::JobSpec spec;
    if (!a.job.empty()) spec = erg::job::load_job_file(a.job);
    erg::v1::WindRegime w;
    w.set_speed_is(erg::v1::WindRegime::WIND_AT_HEIGHT);
    if (a.height_m) w.set_height_m(*a.height_m);
    if (a.roughness_m) w.set_roughness_m(*a.roughness_m);
    {
      erg::v1::JobSpec d;
      *d.mutable_wind() = w;
      erg::job::apply_defaults(d);
      w.set_height_m(d.wind().height_m());
      w.set_roughness_m(d.wind().roughness_m());
    }
    if (w.roughness_m() >= w.height_m())
      throw std::invalid_argument("--roughness " + std::to_string(w.roughness_m()) +
                                  " m must be below --height " + std::to_string(w.height_m()) +
                                  " m");
    const physics::Sand sand = physics::sand_of(spec);
    const double k_ustar = physics::ustar_per_speed(w, sand);

    // Hour by hour: each record interval is one share of the time.
    std::vector<physics::WindShare> hours(n);
    std::vector<std::vector<physics::WindShare>> by_sector(static_cast<std::size_t>(a.sectors));
    const double sector = 360.0 / a.sectors;
    std::vector<int> sector_of(n);
    std::size_t calms = 0;
    for (std::size_t k = 0; k < n; ++k) {
      hours[k] = {erg_direction(rec.u[k], rec.v[k]), std::hypot(rec.u[k], rec.v[k]),
                  1.0 / static_cast<double>(n)};
      // A calm (speed 0) has no direction: no sector, and in the rose an
      // entry of speed 0.
      if (hours[k].speed_mps == 0) {
        sector_of[k] = -1;
        ++calms;
        continue;
      }
      sector_of[k] =
          static_cast<int>(std::lround(bearing_from(rec.u[k], rec.v[k]) / sector)) % a.sectors;
      by_sector[static_cast<std::size_t>(sector_of[k])].push_back(hours[k]);
    }
    const physics::DriftPotential record = physics::drift_potential(sand, k_ustar, hours);

    // The rose: (sector, speed class) cells with the mean speed of their
    // hours and their share of the time; the entry's direction is the
    // sector's centre in erg's convention, spread over the sector.
    erg::v1::WindRose rose;
    rose.set_sector_width_deg(sector);
    {
      std::vector<std::pair<std::pair<int, long>, double>> cells;  // ((sector, class), speed)
      for (std::size_t k = 0; k < n; ++k)
        cells.push_back({{sector_of[k], static_cast<long>(hours[k].speed_mps / a.speed_bin_mps)},
                         hours[k].speed_mps});
      std::sort(cells.begin(), cells.end());
      for (std::size_t i = 0; i < cells.size();) {
        std::size_t j = i;
        double sum = 0;
        for (; j < cells.size() && cells[j].first == cells[i].first; ++j) sum += cells[j].second;
        const int sec = cells[i].first.first;
        double dir = sec < 0 ? 0.0 : -90.0 - sec * sector;  // towards, ccw from +x
        dir = std::remainder(dir, 360.0);
        auto* e = rose.add_entries();
        e->set_direction_deg(tidy(dir));
        e->set_speed_mps(tidy(sum / static_cast<double>(j - i)));
        e->set_probability(static_cast<double>(j - i) / static_cast<double>(n));
        i = j;
      }
    }
    std::vector<physics::WindShare> rose_winds;
    for (const auto& e : rose.entries())
      rose_winds.push_back({e.direction_deg(), e.speed_mps(), e.probability()});
    const physics::DriftPotential binned = physics::drift_potential(sand, k_ustar, rose_winds);

    erg::v1::JobSpec fragment;
    if (a.rose) {
      *w.mutable_rose() = rose;
    } else {
      double step_s = a.step_hours * 3600;
      if (step_s == 0) {
        if (a.job.empty())
          throw std::invalid_argument(
              "a wind.series needs the time of a step: --job JOB.json (the step that job's "
              "calibration measures) or --step-hours H; or import a --rose");
        erg::v1::JobSpec physical = spec;
        *physical.mutable_wind() = w;
        physical.mutable_wind()->mutable_constant()->set_speed_mps(10);
        erg::job::apply_defaults(physical);
        step_s = calibrate(physical).dt_s;
      }
      // Keyframe step = floor((t - t0) / dt), the step the hour begins in. A step has one wind, so
      // the hours that fall on one step become one keyframe that moves the same sand: the direction
      // of their mean flux vector and the speed whose flux (the law's, monotonic above U_t) is its
      // magnitude. A mean wind vector would not do: the flux is cubic above a threshold, so it
      // would lose most of a windy afternoon averaged with a calm night.
      // Below the threshold (no flux) the mean wind vector is kept.
      auto* s = w.mutable_series();
      auto step_of = [&](std::size_t k) {
        return static_cast<std::int64_t>(
            std::floor(static_cast<double>(rec.time_s[k] - rec.time_s[0]) / step_s));
      };
      for (std::size_t i = 0; i < n;) {
        const std::int64_t step = step_of(i);
        std::size_t j = i;
        while (j < n && step_of(j) == step) ++j;
        const std::vector<physics::WindShare> group(hours.begin() + static_cast<long>(i),
                                                    hours.begin() + static_cast<long>(j));
        const physics::DriftPotential q = physics::drift_potential(sand, k_ustar, group);
        double speed = 0, dir = q.rdd_deg;
        if (q.rdp > 0) {
          double lo = physics::threshold(sand) / k_ustar, hi = 100;
          for (int it = 0; it < 100; ++it) {
            const double mid = (lo + hi) / 2;
            (physics::flux_bulk(sand, k_ustar * mid) * static_cast<double>(j - i) <
                     q.rdp * static_cast<double>(n)
                 ? lo
                 : hi) = mid;
          }
          speed = (lo + hi) / 2;
        } else {
          double su = 0, sv = 0;
          for (std::size_t k = i; k < j; ++k) su += rec.u[k], sv += rec.v[k];
          speed = std::hypot(su, sv) / static_cast<double>(j - i);
          dir = erg_direction(su, sv);
        }
        auto* kf = s->add_keyframes();
        kf->set_step(step);
        kf->set_speed_mps(tidy(speed));
        kf->set_direction_deg(tidy(dir));
        i = j;
      }
      std::cerr << "series: " << s->keyframes_size() << " keyframes over steps 0 to "
                << s->keyframes(s->keyframes_size() - 1).step() << ", one step = " << step_s / 3600
                << " h of the record\n";
    }
    *fragment.mutable_wind() = w;
    if (!a.job.empty()) {
      // The wind in its job must pass erg check.
      erg::v1::JobSpec merged = spec;
      *merged.mutable_wind() = w;
      erg::job::apply_defaults(merged);
      const auto problems = erg::job::validate(merged, erg::job::base_dir_of(a.job));
      if (!problems.empty()) throw erg::job::SpecError(problems);
    }

    // The report (stderr: stdout is the fragment).
    std::ostringstream r;
    r.precision(4);
    auto yr = [](double m2_s) { return m2_s * kSecondsPerYear; };
    r << "record: " << n << " winds, " << io::format_iso8601(rec.time_s.front()) << " to "
      << io::format_iso8601(rec.time_s.back())
      << (rec.where.empty() ? std::string() : ", " + rec.where) << "\n"
      << "winds at " << w.height_m()
      << " m over z0 = " << (w.roughness_m() > 0 ? w.roughness_m() : sand.d / 30)
      << " m: u* = " << k_ustar
      << " U (law of the wall); threshold u_t = " << physics::threshold(sand)
      << " m/s, U_t = " << physics::threshold(sand) / k_ustar << " m/s; flux law "
      << physics::law_name(sand) << "\n"
      << "rose (from; share of time, mean speed, drift potential in m^3 per m per year):\n";
    for (int k = 0; k < a.sectors; ++k) {
      const auto& hs = by_sector[static_cast<std::size_t>(k)];
      double share = 0, speed = 0;
      for (const auto& h : hs) share += h.weight, speed += h.speed_mps;
      char line[160];
      std::snprintf(line, sizeof line, "  %-3s %5.1f deg  %5.1f%%  %6.2f m/s  DP %10.4g\n",
                    compass_name(k, a.sectors), k * sector, 100 * share,
                    hs.empty() ? 0.0 : speed / static_cast<double>(hs.size()),
                    yr(physics::drift_potential(sand, k_ustar, hs).dp));
      r << line;
    }
    if (calms)
      r << "  calm " << 100.0 * static_cast<double>(calms) / static_cast<double>(n) << "%\n";
    auto towards_bearing = [](double rdd) {
      double b = 90 - rdd;
      b = std::fmod(b, 360.0);
      return b < 0 ? b + 360 : b;
    };
    r.precision(9);
    for (const auto& [name, d] : {std::pair{"record", record}, std::pair{"rose", binned}})
      r << "drift (" << name << "): DP " << yr(d.dp) << " m^3/m/yr, RDP " << yr(d.rdp)
        << " m^3/m/yr, RDP/DP " << (d.dp > 0 ? d.rdp / d.dp : 0) << ", RDD " << d.rdd_deg
        << " deg ccw from +x (towards; compass " << towards_bearing(d.rdd_deg) << ")\n";

    std::vector<double> petals;
    for (const auto& hs : by_sector)
      petals.push_back(physics::drift_potential(sand, k_ustar, hs).dp);
    io::write_sand_rose_png(a.png, petals, towards_bearing(record.rdd_deg),
                            record.dp > 0 ? record.rdp / record.dp : 0, 400);
    r << "sand rose: " << a.png
      << " (petals point where the wind comes from, length ~ DP; the blue line is the resultant "
         "drift, RDD and RDP/DP)\n";

    std::string json = erg::job::to_readable_json(fragment) + "\n";
    if (a.out.empty()) {
      std::cout << json;
    } else {
      io::write_file_atomic(a.out, json);
      r << "wind: " << a.out << "\n";
    }
    std::cerr << r.str();
    return 0;
  } catch (const std::invalid_argument& e) {
    std::cerr << "erg wind import: " << e.what() << "\n";
    return 2;
  } catch (const erg::job::SpecError& e) {
    std::cerr << "erg wind import: the wind does not fit " << a.job << ":\n" << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "erg wind import: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace erg::client
