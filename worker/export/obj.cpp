// SPDX-License-Identifier: Apache-2.0
// Wavefront OBJ export of a region: one vertex per sample in metres (x east,
// y north, z up), two triangles per quad (counter-clockwise seen from above),
// optional vertex normals from central differences.
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <string>

#include "export/export.h"
#include "io/atomic_file.h"

namespace erg::exporting {

void write_obj(const std::string& path, const Field& f, const Provenance& p, bool normals) {
  const long long nv = static_cast<long long>(f.nx) * f.ny;
  if (nv > kMaxObjVertices)
    throw ExportError(path + ": an OBJ of " + std::to_string(f.nx) + " x " + std::to_string(f.ny) +
                      " vertices is too large (at most " + std::to_string(kMaxObjVertices) +
                      "); export a --region, a smaller --upsample, or --tiles");
  if (f.nx < 2 || f.ny < 2) throw ExportError(path + ": an OBJ needs at least 2 x 2 samples");
  io::detail::AtomicFile out(path);
  FILE* fp = out.open_stdio();
  auto at = [&](int i, int j) { return f.v[static_cast<std::size_t>(j) * f.nx + i]; };
  std::fprintf(fp, "# erg %s: layer %s, step %lld, %d x %d vertices, %.9g m apart\n",
               p.erg_version.c_str(), p.layer.c_str(), p.step, f.nx, f.ny, f.pixel_m);
  std::fprintf(fp, "o erg_%s_step_%lld\n", p.layer.c_str(), p.step);
  for (int j = 0; j < f.ny; ++j)
    for (int i = 0; i < f.nx; ++i)
      std::fprintf(fp, "v %.6f %.6f %.6f\n", f.x0_m + (i + 0.5) * f.pixel_m,
                   f.y0_m + (j + 0.5) * f.pixel_m, static_cast<double>(at(i, j)));
  if (normals) {
    for (int j = 0; j < f.ny; ++j)
      for (int i = 0; i < f.nx; ++i) {
        const int il = i > 0 ? i - 1 : i, ir = i + 1 < f.nx ? i + 1 : i;
        const int jd = j > 0 ? j - 1 : j, ju = j + 1 < f.ny ? j + 1 : j;
        const double dzdx = (at(ir, j) - at(il, j)) / ((ir - il) * f.pixel_m);
        const double dzdy = (at(i, ju) - at(i, jd)) / ((ju - jd) * f.pixel_m);
        const double len = std::sqrt(dzdx * dzdx + dzdy * dzdy + 1);
        std::fprintf(fp, "vn %.5f %.5f %.5f\n", -dzdx / len, -dzdy / len, 1 / len);
      }
  }
  for (int j = 0; j + 1 < f.ny; ++j)
    for (int i = 0; i + 1 < f.nx; ++i) {
      const long long a = static_cast<long long>(j) * f.nx + i + 1;  // OBJ counts from 1
      const long long b = a + 1, c = a + f.nx, d = c + 1;
      if (normals)
        std::fprintf(fp, "f %lld//%lld %lld//%lld %lld//%lld\nf %lld//%lld %lld//%lld %lld//%lld\n",
                     a, a, b, b, d, d, a, a, d, d, c, c);
      else
        std::fprintf(fp, "f %lld %lld %lld\nf %lld %lld %lld\n", a, b, d, a, d, c);
    }
  out.close_stdio(fp);
  out.commit();
}

}  // namespace erg::exporting
