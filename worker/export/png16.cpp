// SPDX-License-Identifier: Apache-2.0
// 16-bit PNG heightmap export with a JSON sidecar: the PNG is what game
// engines import; the sidecar says how to turn its samples back into metres
// and gives the import settings of Unreal's Landscape and Unity's Terrain.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "export/export.h"
#include "io/atomic_file.h"

namespace erg::exporting {

namespace {
std::string g(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}
bool is_pow2_plus_1(int n) {
  const int m = n - 1;
  return m >= 32 && m <= 4096 && (m & (m - 1)) == 0;
}
}  // namespace

void write_png16_export(const std::string& path, const Field& f, const Provenance& p, double lo,
                        double hi) {
  const double range = hi > lo ? hi - lo : 0;
  const double per_unit = range > 0 ? range / 65535.0 : 1.0 / 65535.0;
  std::vector<double> v01(f.v.size());
  for (std::size_t k = 0; k < f.v.size(); ++k)
    v01[k] = range > 0 ? (static_cast<double>(f.v[k]) - lo) / range : 0.0;
  try {
    io::write_png16(path, f.nx, f.ny, v01);
  } catch (const io::IoError& e) {
    throw ExportError(e.what());
  }
  // Unreal Landscape: Z scale 100 (%) spans 512 m over the 65536 levels
  // (1/128 m per level, level 32768 at the actor's Z), so a range of R m
  // needs Z scale = 12800 R / 65535 (about R / 512 * 100); one vertex per
  // pixel, XY scale = pixel size in cm.
  const double ue_z = 12800.0 * range / 65535.0;
  const double ue_loc_z_cm = 100.0 * lo + 32768.0 * 100.0 * per_unit;
  const bool unity_ok = f.nx == f.ny && is_pow2_plus_1(f.nx);
  std::string j = "{\n";
  j += "  \"file\": \"" + path.substr(path.find_last_of('/') + 1) + "\",\n";
  j += "  \"layer\": \"" + p.layer + "\",\n";
  j += "  \"step\": " + std::to_string(p.step) + ",\n";
  j += "  \"time_days\": " + g(p.time_days) + ",\n";
  j += "  \"width\": " + std::to_string(f.nx) + ",\n";
  j += "  \"height\": " + std::to_string(f.ny) + ",\n";
  j += "  \"first_row\": \"north\",\n";
  j += "  \"cell_size_m\": " + g(f.pixel_m) + ",\n";
  j += "  \"origin_m\": [" + g(f.x0_m) + ", " + g(f.y0_m) + "],\n";
  j += "  \"metres_per_unit\": " + g(per_unit) + ",\n";
  j += "  \"offset_m\": " + g(lo) + ",\n";
  j += "  \"min_m\": " + g(lo) + ",\n";
  j += "  \"max_m\": " + g(hi) + ",\n";
  j += "  \"range_m\": " + g(range) + ",\n";
  j += "  \"formula\": \"metres = offset_m + metres_per_unit * sample\",\n";
  j += "  \"unreal\": {\"scale_x_cm\": " + g(100 * f.pixel_m) +
       ", \"scale_y_cm\": " + g(100 * f.pixel_m) + ", \"scale_z_percent\": " + g(ue_z) +
       ", \"location_z_cm\": " + g(ue_loc_z_cm) +
       ", \"note\": \"Landscape > Import from File; Z scale 100 = 512 m over " +
       "65536 levels\"},\n";
  j += "  \"unity\": {\"heightmap_resolution\": " + std::to_string(f.nx) +
       ", \"resolution_ok\": " + (unity_ok ? "true" : "false") +
       ", \"terrain_width_m\": " + g((f.nx - 1) * f.pixel_m) +
       ", \"terrain_length_m\": " + g((f.ny - 1) * f.pixel_m) +
       ", \"terrain_height_m\": " + g(range) + ", \"position_y_m\": " + g(lo) +
       ", \"note\": \"square, 2^n+1 samples (33..4097); import as RAW 16-bit\"}\n";
  j += "}\n";
  io::detail::AtomicFile side(path + ".json");
  side.write_whole(j.data(), j.size());
  side.commit();
}

}  // namespace erg::exporting
